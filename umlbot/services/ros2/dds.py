"""The DDS side of ROS 2, with cyclonedds: a loopback-only participant, message types built at run
time from their definitions, topic readers and writers, and service clients and servers in
rmw_cyclonedds' layout.

ROS 2's conventions (what rmw_cyclonedds and rmw_fastrtps put on the wire): topic `/cmd_vel` is
DDS topic `rt/cmd_vel`; type `geometry_msgs/msg/Twist` is `geometry_msgs::msg::dds_::Twist_`;
samples are classic little-endian CDR (XCDR1). A service `/x` is the topics `rq/xRequest` and
`rr/xReply`; each sample starts with rmw_cyclonedds' 16-byte header (`uint64 guid; int64 seq`),
a reply carries the request's header, so the client takes its own replies by guid and seq.

Loopback only unless told otherwise: without `CYCLONEDDS_URI` in the environment, a domain is
created with `LOOPBACK_CONFIG` (interface `lo`, no multicast, the peer 127.0.0.1).
"""

from __future__ import annotations

import itertools
import os
import random
import struct
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from umlbot.base.errors import ConfigError
from umlbot.base.logs import get_logger
from umlbot.services.ros2 import missing_extra
from umlbot.services.ros2.msgtypes import ARRAY, BASE, NAME, SEQUENCE, Types, dds_type_name

log = get_logger("umlbot.ros2")

LOOPBACK_CONFIG = (
    "<CycloneDDS><Domain><General><Interfaces><NetworkInterface name=\"lo\"/></Interfaces>"
    "<AllowMulticast>false</AllowMulticast></General><Discovery><ParticipantIndex>auto</ParticipantIndex>"
    "<MaxAutoParticipantIndex>60</MaxAutoParticipantIndex>"
    "<Peers><Peer address=\"127.0.0.1\"/></Peers></Discovery></Domain></CycloneDDS>"
)

try:
    from cyclonedds.core import DDSException, InstanceState, Policy, Qos, SampleState, ViewState
    from cyclonedds.core import Listener as _Listener
    from cyclonedds.domain import Domain, DomainParticipant
    from cyclonedds.idl import make_idl_struct
    from cyclonedds.idl import types as _idl_types
    from cyclonedds.pub import DataWriter
    from cyclonedds.sub import DataReader
    from cyclonedds.topic import Topic
    from cyclonedds.util import duration

    try:  # the C layer's raw take and write: CDR bytes in and out (see `FlatCodec`)
        from cyclonedds._clayer import ddspy_take as _raw_take
        from cyclonedds._clayer import ddspy_write as _raw_write
    except ImportError:  # pragma: no cover - another cyclonedds build: the generic path
        _raw_take = _raw_write = None

    # cyclonedds' typing does not describe its generic IDL types and its listener: Any here
    idl: Any = _idl_types
    Listener: Any = _Listener
    #: every sample, read or not (what `DataReader.take` takes)
    ANY_STATE = SampleState.Any | ViewState.Any | InstanceState.Any
    HAVE_CYCLONEDDS = True
except ImportError:  # pragma: no cover - the extra is installed wherever tests run
    HAVE_CYCLONEDDS = False


def require() -> None:
    """Raise the "install the extra" error when cyclonedds is missing."""
    if not HAVE_CYCLONEDDS:
        raise missing_extra("cyclonedds")


# ------------------------------------------------------------------------------------------------
# types


_BASE_IDL: dict[str, Any] = {}


def _base(name: str, bound: int) -> Any:
    if not _BASE_IDL:
        _BASE_IDL.update({
            "bool": bool, "byte": idl.uint8, "char": idl.uint8, "octet": idl.uint8,
            "int8": idl.int8, "uint8": idl.uint8, "int16": idl.int16, "uint16": idl.uint16,
            "int32": idl.int32, "uint32": idl.uint32, "int64": idl.int64, "uint64": idl.uint64,
            "float32": idl.float32, "float64": idl.float64, "string": str,
        })
    if name == "string" and bound:
        return idl.bounded_str[bound]
    if name not in _BASE_IDL:
        raise ValueError(f"the ROS type {name} is not supported")
    return _BASE_IDL[name]


class TypeBuilder:
    """cyclonedds classes for ROS 2 message types (one per type name, made once), and default
    samples of them (zeros, empty strings and sequences). `TypeBuilder.of(types)` is shared: the
    readers and writers of one topic in a process use the same class."""

    _shared: dict[int, TypeBuilder] = {}

    @classmethod
    def of(cls, types: Types) -> TypeBuilder:
        with _plock:
            builder = cls._shared.get(id(types))
            if builder is None:
                builder = cls._shared[id(types)] = cls(types)
            return builder

    def __init__(self, types: Types) -> None:
        require()
        self.types = types
        self._classes: dict[str, Any] = {}
        self._lock = threading.RLock()

    def cls(self, typename: str, header: bool = False) -> Any:
        """The class of a message; `header=True`: with rmw_cyclonedds' service header first."""
        key = typename + ("#header" if header else "")
        with self._lock:
            if key in self._classes:
                return self._classes[key]
            fields: dict[str, Any] = {}
            if header:
                fields |= {"rmw_guid": idl.uint64, "rmw_seq": idl.int64}
            for name, node in self.types.fields(typename):
                fields[name] = self._node(node)
            if not fields:  # ROS 2 gives an empty message one uint8 (`structure_needs_at_least_one_member`)
                fields["structure_needs_at_least_one_member"] = idl.uint8
            _pkg, _sub, name = typename.split("/")
            made = make_idl_struct(f"{name}_", dds_type_name(typename), fields)
            self._classes[key] = made
            return made

    def _node(self, node: Any) -> Any:
        kind, detail = node
        if kind == BASE:
            return _base(detail[0], detail[1])
        if kind == NAME:
            return self.cls(detail)
        if kind == ARRAY:
            return idl.array[self._node(detail[0]), detail[1]]
        if kind == SEQUENCE:
            sub = self._node(detail[0])
            return idl.sequence[sub, detail[1]] if detail[1] else idl.sequence[sub]
        raise ValueError(f"unknown ROS type node {node!r}")

    def default(self, typename: str, header: bool = False) -> Any:
        """A sample of the type with every field zero (empty strings and sequences)."""
        values: dict[str, Any] = {}
        if header:
            values |= {"rmw_guid": 0, "rmw_seq": 0}
        fields = self.types.fields(typename)
        for name, node in fields:
            values[name] = self._default_of(node)
        if not fields:
            values["structure_needs_at_least_one_member"] = 0
        return self.cls(typename, header)(**values)

    def _default_of(self, node: Any) -> Any:
        kind, detail = node
        if kind == BASE:
            return {"bool": False, "string": "", "float32": 0.0, "float64": 0.0}.get(detail[0], 0)
        if kind == NAME:
            return self.default(detail)
        if kind == ARRAY:
            return [self._default_of(detail[0]) for _ in range(detail[1])]
        return []


def get_path(sample: Any, path: str) -> Any:
    for part in path.split("."):
        sample = getattr(sample, part)
    return sample


def set_path(sample: Any, path: str, value: Any) -> None:
    *parents, last = path.split(".")
    for part in parents:
        sample = getattr(sample, part)
    setattr(sample, last, value)


# ------------------------------------------------------------------------------------------------
# flat messages: classic CDR in one pass


#: the encapsulation header of classic little-endian CDR (XCDR1, PLAIN_CDR_LE)
CDR_LE = b"\x00\x01\x00\x00"
_U32 = struct.Struct("<I")
#: base type -> (struct format, size = alignment in XCDR1)
_FLAT: dict[str, tuple[struct.Struct, int]] = {
    name: (struct.Struct("<" + fmt), struct.calcsize(fmt)) for name, fmt in {
        "bool": "?", "byte": "B", "char": "B", "octet": "B", "int8": "b", "uint8": "B",
        "int16": "h", "uint16": "H", "int32": "i", "uint32": "I", "int64": "q", "uint64": "Q",
        "float32": "f", "float64": "d"}.items()}


class FlatCodec:
    """Classic little-endian CDR of a message whose fields are all numbers, bools and strings
    (services' requests and responses: `std_srvs`, `umlbot_msgs/srv/CallFeature`), encoded and
    decoded in one pass with `struct`: the same bytes as cyclonedds' serialiser (tests check
    it), in a few µs instead of its 10-35 µs of Python per sample, on the call's path.
    `FlatCodec.of` is None for any other message (nested, arrays, sequences)."""

    def __init__(self, cls: Any, fields: list[tuple[str, struct.Struct | None, int, int]]) -> None:
        self.cls = cls
        #: (name, format or None for a string, size (alignment), bound of a string)
        self.fields = fields
        #: every field's zero (False, 0, 0.0, "")
        self.defaults: dict[str, Any] = {
            name: "" if fmt is None else fmt.unpack(bytes(size))[0] for name, fmt, size, _ in fields}

    @classmethod
    def of(cls, builder: TypeBuilder, typename: str, header: bool = False) -> FlatCodec | None:
        fields: list[tuple[str, struct.Struct | None, int, int]] = []
        if header:
            fields += [("rmw_guid", _FLAT["uint64"][0], 8, 0), ("rmw_seq", _FLAT["int64"][0], 8, 0)]
        for name, (kind, detail) in builder.types.fields(typename):
            if kind != BASE:
                return None
            base, bound = detail[0], detail[1]
            if base == "string":
                fields.append((name, None, 4, int(bound or 0)))
            elif base in _FLAT:
                fmt, size = _FLAT[base]
                fields.append((name, fmt, size, 0))
            else:
                return None
        if len(fields) == (2 if header else 0):  # ROS 2's one uint8 of an empty message
            fields.append(("structure_needs_at_least_one_member", _FLAT["uint8"][0], 1, 0))
        return cls(builder.cls(typename, header), fields)

    def encode(self, sample: Any) -> bytes:
        """The sample's bytes as a DDS writer sends them (header, body, padded to 4)."""
        out = bytearray(CDR_LE)
        try:
            for name, fmt, size, bound in self.fields:
                value = getattr(sample, name)
                pad = -(len(out) - 4) % size
                if pad:
                    out += bytes(pad)
                if fmt is None:
                    raw = value.encode("utf-8")
                    if bound and len(value) > bound:
                        raise ValueError(f"{name}: {len(value)} characters, at most {bound}")
                    out += _U32.pack(len(raw) + 1)
                    out += raw
                    out += b"\0"
                else:
                    out += fmt.pack(value)
        except (struct.error, OverflowError, AttributeError) as exc:
            raise ValueError(f"{self.cls.__name__}: {exc}") from exc
        pad = -len(out) % 4
        if pad:
            out += bytes(pad)
        return bytes(out)

    def decode(self, data: bytes) -> Any:
        """A sample of the class from its bytes; ValueError for bytes that are not one
        (big-endian CDR too: `decode_any` hands it to cyclonedds)."""
        if data[:2] != CDR_LE[:2]:
            raise ValueError(f"not little-endian classic CDR: {bytes(data[:4]).hex()}")
        values: dict[str, Any] = {}
        pos = 4
        try:
            for name, fmt, size, _bound in self.fields:
                pos += -(pos - 4) % size
                if fmt is None:
                    (length,) = _U32.unpack_from(data, pos)
                    pos += 4
                    if pos + length > len(data):
                        raise ValueError(f"{name}: a string of {length} bytes past the end")
                    values[name] = bytes(data[pos:pos + length - 1]).decode("utf-8") if length else ""
                    pos += length
                else:
                    (values[name],) = fmt.unpack_from(data, pos)
                    pos += size
        except (struct.error, UnicodeDecodeError) as exc:
            raise ValueError(f"{self.cls.__name__}: {exc}") from exc
        return self.cls(**values)

    def decode_any(self, data: bytes) -> Any:
        """`decode`, or cyclonedds' own deserialiser for what it does not read (big-endian)."""
        if data[1:2] == CDR_LE[1:2]:
            return self.decode(data)
        return self.cls.deserialize(data)


# ------------------------------------------------------------------------------------------------
# participants


_domains: dict[int, Any] = {}
_participants: dict[int, Any] = {}
_plock = threading.Lock()


def participant(domain_id: int = 0) -> Any:
    """This process's one participant in a domain (made on first use, loopback unless
    `CYCLONEDDS_URI` says otherwise)."""
    require()
    with _plock:
        if domain_id not in _participants:
            if not os.environ.get("CYCLONEDDS_URI") and domain_id not in _domains:
                _domains[domain_id] = Domain(domain_id, LOOPBACK_CONFIG)
            _participants[domain_id] = DomainParticipant(domain_id)
        return _participants[domain_id]


def qos(reliable: bool, depth: int = 10, latched: bool = False) -> Any:
    """ROS 2's default QoS (keep last, volatile) with classic CDR, reliable or best effort;
    `latched`: transient local, the last sample kept for readers that come later (ROS 2's
    "latched" topics; volatile readers match it too)."""
    reliability = (Policy.Reliability.Reliable(max_blocking_time=duration(milliseconds=100)) if reliable
                   else Policy.Reliability.BestEffort)
    durability = Policy.Durability.TransientLocal if latched else Policy.Durability.Volatile
    return Qos(reliability, Policy.History.KeepLast(1 if latched else depth), durability,
               Policy.DataRepresentation(use_cdrv0_representation=True))


_topics: dict[tuple[int, str], Any] = {}


def shared_topic(dp: Any, name: str, cls: Any) -> Any:
    """One Topic per participant and name (every reader and writer of it in this process uses
    it: a topic's QoS must be the same for all of them); the QoS is on the readers and writers."""
    key = (id(dp), name)
    with _plock:
        topic = _topics.get(key)
        if topic is None:
            topic = _topics[key] = Topic(dp, name, cls, qos=qos(True))
        elif topic.data_type.__idl_typename__ != cls.__idl_typename__:
            raise ConfigError(f"topic {name} carries {topic.data_type.__idl_typename__} here, not "
                              f"{cls.__idl_typename__}: one topic, one type")
        return topic


@dataclass
class Received:
    """The last sample a reader took, when (monotonic), and how many came."""

    sample: Any = None
    at: float = 0.0
    count: int = 0
    bad: int = 0
    error: str = ""


class Subscription:
    """A ROS 2 topic read by this process: keeps the latest sample, calls `on_sample` for each
    (from a DDS thread: keep it short)."""

    def __init__(self, builder: TypeBuilder, domain_id: int, topic: str, typename: str, *,
                 reliable: bool = False, on_sample: Callable[[Any], None] | None = None) -> None:
        from umlbot.services.ros2.msgtypes import dds_topic_name

        self.topic, self.typename = topic, typename
        self.last = Received()
        self._cond = threading.Condition()
        self._on_sample = on_sample
        dp = participant(domain_id)
        self._topic = shared_topic(dp, dds_topic_name(topic), builder.cls(typename))
        self._reader = DataReader(dp, self._topic, qos=qos(reliable),
                                  listener=Listener(on_data_available=self._available))

    def _available(self, reader: Any) -> None:
        try:
            samples = reader.take(N=32)
        except Exception as exc:  # a sample that does not deserialise: a peer sent garbage
            with self._cond:
                self.last.bad += 1
                self.last.error = f"{type(exc).__name__}: {exc}"
            log.warning("ros2_bad_sample", topic=self.topic, type=self.typename, error=str(exc))
            return
        for sample in samples:
            if not isinstance(sample, self._topic.data_type):  # invalid samples (disposals)
                continue
            with self._cond:
                self.last = Received(sample, time.monotonic(), self.last.count + 1, self.last.bad,
                                     self.last.error)
                self._cond.notify_all()
            if self._on_sample is not None:
                try:
                    self._on_sample(sample)
                except Exception:
                    log.exception("ros2_on_sample_failed", topic=self.topic)

    def wait(self, timeout_s: float, after: int = 0) -> Received:
        """The latest sample once more than `after` samples came, or what there is at the timeout."""
        with self._cond:
            self._cond.wait_for(lambda: self.last.count > after, timeout_s)
            return self.last

    def close(self) -> None:
        for entity in (self._reader,):  # the topic is shared (`shared_topic`)
            try:
                entity.__del__()
            except Exception:  # already gone
                log.debug("ros2_close", topic=self.topic)


class Publication:
    """A ROS 2 topic this process publishes (reliable: matches reliable and best-effort readers)."""

    def __init__(self, builder: TypeBuilder, domain_id: int, topic: str, typename: str,
                 latched: bool = False) -> None:
        from umlbot.services.ros2.msgtypes import dds_topic_name

        self.topic, self.typename = topic, typename
        self.builder = builder
        dp = participant(domain_id)
        self._topic = shared_topic(dp, dds_topic_name(topic), builder.cls(typename))
        self._writer = DataWriter(dp, self._topic, qos=qos(True, latched=latched))
        self._lock = threading.Lock()

    def sample(self) -> Any:
        return self.builder.default(self.typename)

    def write(self, sample: Any, confirm_s: float = 0.0) -> bool:
        """Write a sample; with `confirm_s`, wait that long at most until every matched reliable
        reader has acknowledged it (False when one did not)."""
        with self._lock:
            self._writer.write(sample)
            if confirm_s > 0:
                return bool(self._writer.wait_for_acks(duration(seconds=confirm_s)))
        return True

    def matched(self) -> int:
        """How many readers this writer has found."""
        return len(self._writer.get_matched_subscriptions())

    def close(self) -> None:
        for entity in (self._writer,):
            try:
                entity.__del__()
            except Exception:
                log.debug("ros2_close", topic=self.topic)


class ServiceTimeout(TimeoutError):
    """No reply (or no server) within the call's timeout."""


class _ServiceEndpoint:
    """What a service's client and server share (rmw_cyclonedds' layout): the request topic
    `rq/<name>Request` and the reply topic `rr/<name>Reply`, both with the 16-byte header; one
    writes to one of them and reads the other. Samples of flat types (`FlatCodec`: every
    service umlbot ships) are taken and written as CDR bytes through the C layer, decoded and
    encoded in one pass; any other type goes through cyclonedds' own (de)serialiser."""

    def __init__(self, builder: TypeBuilder, domain_id: int, service: str, srv_type: str,
                 serving: bool) -> None:
        self.service, self.srv_type = service, srv_type
        self.builder = builder
        name = service.lstrip("/")
        dp = participant(domain_id)
        self._req_type, self._rep_type = f"{srv_type}_Request", f"{srv_type}_Response"
        req_topic = shared_topic(dp, f"rq/{name}Request", builder.cls(self._req_type, True))
        rep_topic = shared_topic(dp, f"rr/{name}Reply", builder.cls(self._rep_type, True))
        requests, replies = (req_topic, self._req_type), (rep_topic, self._rep_type)
        # a server reads requests and writes replies; a client the other way round
        (in_topic, in_type), (out_topic, out_type) = (requests, replies) if serving else (replies, requests)
        self._in_cls = in_topic.data_type
        self._in_codec = FlatCodec.of(builder, in_type, True) if _raw_take is not None else None
        self._out_codec = FlatCodec.of(builder, out_type, True) if _raw_write is not None else None
        #: samples taken that did not decode (a peer sent garbage)
        self.bad = 0
        self._writer = DataWriter(dp, out_topic, qos=qos(True))
        self._reader = DataReader(dp, in_topic, qos=qos(True),
                                  listener=Listener(on_data_available=self._available))

    def _take(self) -> list[Any]:
        """The samples waiting (at most 32), invalid ones (disposals) left out; raises for a
        sample that does not decode (the generic path: for the whole batch)."""
        codec = self._in_codec
        if codec is None:
            return [s for s in self._reader.take(N=32) if isinstance(s, self._in_cls)]
        taken = _raw_take(self._reader._ref, ANY_STATE, 32)
        if isinstance(taken, int):
            raise DDSException(taken, f"taking from {self.service}")
        samples = []
        for data, info in taken:
            if info.valid_data:
                try:
                    samples.append(codec.decode_any(data))
                except ValueError as exc:
                    self._bad(exc)
        return samples

    def _write(self, sample: Any) -> None:
        codec = self._out_codec
        if codec is None:
            self._writer.write(sample)
            return
        ret = _raw_write(self._writer._ref, codec.encode(sample))
        if ret < 0:
            raise DDSException(ret, f"writing to {self.service}")

    def _available(self, reader: Any) -> None:
        try:
            samples = self._take()
        except Exception as exc:  # a sample that does not deserialise: a peer sent garbage
            self._bad(exc)
            return
        self._handle(samples)

    def _handle(self, samples: list[Any]) -> None:
        raise NotImplementedError

    def _bad(self, exc: Exception) -> None:
        self.bad += 1
        log.warning("ros2_bad_sample", service=self.service, error=f"{type(exc).__name__}: {exc}")

    def close(self) -> None:
        for entity in (self._reader, self._writer):
            try:
                entity.__del__()
            except Exception:
                log.debug("ros2_close", service=self.service)


class ServiceClient(_ServiceEndpoint):
    """Calls a ROS 2 service the way rmw_cyclonedds does: requests on `rq/<name>Request` with
    the 16-byte header (this client's guid, a sequence number), replies taken from
    `rr/<name>Reply` by that header."""

    def __init__(self, builder: TypeBuilder, domain_id: int, service: str, srv_type: str) -> None:
        super().__init__(builder, domain_id, service, srv_type, serving=False)
        self.guid = random.getrandbits(63)
        self._seq = itertools.count(1)
        self._replies: dict[int, Any] = {}
        self._cond = threading.Condition()

    def request(self) -> Any:
        """An empty request to fill in."""
        return self.builder.default(self._req_type, True)

    def _handle(self, samples: list[Any]) -> None:
        with self._cond:
            for sample in samples:
                if sample.rmw_guid == self.guid:
                    self._replies[sample.rmw_seq] = sample
            self._cond.notify_all()

    def wait_for_server(self, timeout_s: float) -> bool:
        deadline = time.monotonic() + timeout_s
        while time.monotonic() < deadline:
            if self._writer.get_matched_subscriptions() and self._reader.get_matched_publications():
                return True
            time.sleep(0.01)
        return False

    def call(self, request: Any, timeout_s: float) -> Any:
        """Send a request and wait for its reply; `ServiceTimeout` when no server or no reply."""
        deadline = time.monotonic() + timeout_s
        if not self.wait_for_server(timeout_s):
            raise ServiceTimeout(f"no ROS 2 server for service {self.service} ({self.srv_type}) "
                                 f"within {timeout_s:g} s")
        seq = next(self._seq)
        request.rmw_guid, request.rmw_seq = self.guid, seq
        self._write(request)
        with self._cond:
            got = self._cond.wait_for(lambda: seq in self._replies, max(0.0, deadline - time.monotonic()))
            if not got:
                raise ServiceTimeout(f"service {self.service} did not reply within {timeout_s:g} s")
            return self._replies.pop(seq)


class ServiceServer(_ServiceEndpoint):
    """Serves a ROS 2 service in rmw_cyclonedds' layout: `handler(request) -> response` (a sample
    of `<srv>_Response`, `response()` makes one; the header is copied from the request). The
    handler runs on DDS's listener thread, or in `executor` when given (a handler that waits).
    A handler that returns None answers later with `respond(request, response)`."""

    def __init__(self, builder: TypeBuilder, domain_id: int, service: str, srv_type: str,
                 handler: Callable[[Any], Any], executor: Any = None) -> None:
        self.handler = handler
        self.served = 0
        self.executor = executor
        super().__init__(builder, domain_id, service, srv_type, serving=True)

    def response(self) -> Any:
        return self.builder.default(self._rep_type, True)

    def response_of(self, request: Any, **fields: Any) -> Any:
        """The response to `request` with these fields and the rest zero: made in one step (no
        default sample to fill in), for a handler on the call's path."""
        codec = self._out_codec
        if codec is None:
            response = self.response()
            for name, value in fields.items():
                setattr(response, name, value)
        else:
            response = codec.cls(**(codec.defaults | fields))
        response.rmw_guid, response.rmw_seq = request.rmw_guid, request.rmw_seq
        return response

    def _handle(self, samples: list[Any]) -> None:
        for request in samples:
            if self.executor is not None:
                self.executor.submit(self._serve, request)
            else:
                self._serve(request)

    def _serve(self, request: Any) -> None:
        try:
            response = self.handler(request)
            if response is not None:
                self.respond(request, response)
        except Exception:
            log.exception("ros2_service_handler_failed", service=self.service)

    def respond(self, request: Any, response: Any) -> None:
        """Send the response to `request` (to the client that sent it, by its header)."""
        response.rmw_guid, response.rmw_seq = request.rmw_guid, request.rmw_seq
        self._write(response)
        self.served += 1
