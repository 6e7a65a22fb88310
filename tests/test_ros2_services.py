"""ROS 2 services in rmw_cyclonedds' layout: umlbot's one-pass CDR of flat samples (`FlatCodec`)
against cyclonedds' own serialiser and rosbags, and umlbot's service client and server against a
Cyclone DDS peer written here on plain cyclonedds (its own types, topic names and header spelled
out in the peer, none of umlbot's service code), in another process, on loopback."""

from __future__ import annotations

import os
import subprocess
import sys
import time
from collections.abc import Iterator
from typing import Any

import pytest
from ros2_support import session_domain

from umlbot.services.ros2 import dds
from umlbot.services.ros2.msgtypes import Types

DOMAIN = session_domain()

#: every service umlbot ships, request and response, with values that are not the defaults
SAMPLES: dict[str, dict[str, Any]] = {
    "std_srvs/srv/Empty_Request": {},
    "std_srvs/srv/Empty_Response": {},
    "std_srvs/srv/SetBool_Request": {"data": True},
    "std_srvs/srv/SetBool_Response": {"success": True, "message": "lamp on"},
    "std_srvs/srv/Trigger_Request": {},
    "std_srvs/srv/Trigger_Response": {"success": False, "message": "zu heiß: 93 °C"},
    "umlbot_msgs/srv/CallFeature_Request": {"component": "Sonar", "feature": "value",
                                             "args_json": "[1, 2.5]", "timeout_s": 1.25},
    "umlbot_msgs/srv/CallFeature_Response": {"ok": True, "value_json": "{\"a\":[1,2]}",
                                              "error_code": "", "error_message": "x"},
}


@pytest.fixture(scope="module")
def builder() -> dds.TypeBuilder:
    return dds.TypeBuilder.of(Types.load())


def _sample(builder: dds.TypeBuilder, typename: str, **values: Any) -> Any:
    sample = builder.default(typename, header=True)
    sample.rmw_guid, sample.rmw_seq = 0x8102030405060708, 77
    for name, value in values.items():
        setattr(sample, name, value)
    return sample


def _padded(data: bytes) -> bytes:
    return data.ljust((len(data) + 3) & ~3, b"\0")  # as cyclonedds' DataWriter.write pads


@pytest.mark.parametrize("typename", sorted(SAMPLES))
def test_flat_samples_are_the_bytes_cyclonedds_and_rosbags_make(builder: dds.TypeBuilder,
                                                                typename: str) -> None:
    codec = dds.FlatCodec.of(builder, typename, header=True)
    assert codec is not None
    sample = _sample(builder, typename, **SAMPLES[typename])
    theirs = _padded(sample.serialize(use_version_2=False))
    assert codec.encode(sample) == theirs
    assert codec.decode(theirs) == sample
    # the body after rmw_cyclonedds' 16-byte header is the ROS 2 message as rosbags reads it
    body = Types.load().store.deserialize_cdr(dds.CDR_LE + theirs[20:], typename)
    for name, value in SAMPLES[typename].items():
        assert getattr(body, name) == value


def test_flat_codec_refuses_what_is_not_a_sample(builder: dds.TypeBuilder) -> None:
    typename = "umlbot_msgs/srv/CallFeature_Request"
    codec = dds.FlatCodec.of(builder, typename, header=True)
    assert codec is not None
    good = codec.encode(_sample(builder, typename, **SAMPLES[typename]))
    with pytest.raises(ValueError, match="CallFeature_Request"):
        codec.decode(good[:30])  # cut inside the first string
    with pytest.raises(ValueError, match="past the end"):
        codec.decode(good[:20] + (10_000).to_bytes(4, "little") + good[24:])
    with pytest.raises(ValueError, match="CallFeature_Request"):
        codec.decode(good[:24] + b"\xff\xfe" + good[26:])  # not UTF-8
    with pytest.raises(ValueError, match="not little-endian"):
        codec.decode(b"\x00\x00\x00\x00" + good[4:])
    with pytest.raises(ValueError, match="at most 3"):
        bounded = dds.FlatCodec(codec.cls, [("component", None, 4, 3)])
        bounded.encode(_sample(builder, typename, component="Sonar"))
    with pytest.raises(ValueError, match="SetBool_Response"):
        response = dds.FlatCodec.of(builder, "std_srvs/srv/SetBool_Response", header=True)
        assert response is not None
        response.encode(_sample(builder, "std_srvs/srv/SetBool_Response", message=7))
    # big-endian CDR (another vendor's choice) goes to cyclonedds' own reader
    sample = _sample(builder, typename, **SAMPLES[typename])
    from cyclonedds.idl._support import Endianness

    big = sample.serialize(use_version_2=False, endianness=Endianness.Big)
    assert big[:2] == b"\x00\x00"
    assert codec.decode_any(big) == sample


def test_only_flat_types_get_the_codec(builder: dds.TypeBuilder) -> None:
    assert dds.FlatCodec.of(builder, "geometry_msgs/msg/Twist") is None  # nested
    assert dds.FlatCodec.of(builder, "sensor_msgs/msg/Range") is None  # header (nested)
    float64 = dds.FlatCodec.of(builder, "std_msgs/msg/Float64")
    assert float64 is not None and [f[0] for f in float64.fields] == ["data"]


PLAIN_PEER = """
import sys, time
from cyclonedds.core import Listener, Policy, Qos
from cyclonedds.domain import DomainParticipant
from cyclonedds.idl import make_idl_struct
from cyclonedds.idl import types as t
from cyclonedds.pub import DataWriter
from cyclonedds.sub import DataReader
from cyclonedds.topic import Topic
from cyclonedds.util import duration

dp = DomainParticipant(int(sys.argv[1]))
qos = Qos(Policy.Reliability.Reliable(duration(milliseconds=100)), Policy.History.KeepLast(10),
          Policy.DataRepresentation(use_cdrv0_representation=True))
head = {"rmw_guid": t.uint64, "rmw_seq": t.int64}
SetReq = make_idl_struct("SetBool_Request_", "std_srvs::srv::dds_::SetBool_Request_", {**head, "data": bool})
SetRep = make_idl_struct("SetBool_Response_", "std_srvs::srv::dds_::SetBool_Response_",
                         {**head, "success": bool, "message": str})
TrigReq = make_idl_struct("Trigger_Request_", "std_srvs::srv::dds_::Trigger_Request_",
                          {**head, "structure_needs_at_least_one_member": t.uint8})
TrigRep = make_idl_struct("Trigger_Response_", "std_srvs::srv::dds_::Trigger_Response_",
                          {**head, "success": bool, "message": str})

CallReq = make_idl_struct("CallFeature_Request_", "umlbot_msgs::srv::dds_::CallFeature_Request_",
                          {**head, "component": str, "feature": str, "args_json": str, "timeout_s": float})
bad = DataWriter(dp, Topic(dp, "rq/plain/callRequest", CallReq), qos=qos)

# a server of /plain/set (std_srvs/srv/SetBool)
replies = DataWriter(dp, Topic(dp, "rr/plain/setReply", SetRep), qos=qos)
def serve(reader):
    for request in reader.take(N=8):
        if isinstance(request, SetReq):
            print(f"request {request.rmw_guid:x} {request.rmw_seq} {request.data}", flush=True)
            replies.write(SetRep(rmw_guid=request.rmw_guid, rmw_seq=request.rmw_seq,
                                 success=not request.data, message=f"seq {request.rmw_seq}"))
requests = DataReader(dp, Topic(dp, "rq/plain/setRequest", SetReq), qos=qos,
                      listener=Listener(on_data_available=serve))

# a client of /plain/serve (std_srvs/srv/Trigger)
ask = DataWriter(dp, Topic(dp, "rq/plain/serveRequest", TrigReq), qos=qos)
answers = DataReader(dp, Topic(dp, "rr/plain/serveReply", TrigRep), qos=qos)
print("ready", flush=True)
for line in sys.stdin:
    if line.strip() == "garbage":  # a CallFeature request whose component is not UTF-8
        from cyclonedds._clayer import ddspy_write
        data = CallReq(rmw_guid=5, rmw_seq=6, component="\u00ff\u00fe", feature="value", args_json="",
                       timeout_s=0.0).serialize(use_version_2=False)
        data = data.replace("\u00ff\u00fe".encode(), b"\\xff\\xfe\\xff\\xfe")  # same length
        print("garbage", ddspy_write(bad._ref, data.ljust((len(data) + 3) & ~3, b"\\0")), flush=True)
        continue
    if line.strip() != "call":
        continue
    deadline = time.monotonic() + 10
    while not (ask.get_matched_subscriptions() and answers.get_matched_publications()):
        if time.monotonic() > deadline:
            sys.exit("no server for /plain/serve")
        time.sleep(0.02)
    ask.write(TrigReq(rmw_guid=0xABCDEF, rmw_seq=41, structure_needs_at_least_one_member=0))
    got = None
    while got is None and time.monotonic() < deadline:
        for reply in answers.take(N=8):
            if isinstance(reply, TrigRep) and (reply.rmw_guid, reply.rmw_seq) == (0xABCDEF, 41):
                got = reply
        time.sleep(0.005)
    print(f"reply {got.success} {got.message}" if got else "reply none", flush=True)
"""


@pytest.fixture
def plain_peer() -> Iterator[subprocess.Popen[str]]:
    env = {**os.environ, "CYCLONEDDS_URI": dds.LOOPBACK_CONFIG}
    process = subprocess.Popen([sys.executable, "-c", PLAIN_PEER, str(DOMAIN)], stdin=subprocess.PIPE,
                               stdout=subprocess.PIPE, text=True, env=env)
    try:
        assert process.stdout is not None
        assert process.stdout.readline().strip() == "ready"
        yield process
    finally:
        process.kill()
        process.wait(10)


def test_client_and_server_against_a_plain_cyclone_dds_peer(builder: dds.TypeBuilder,
                                                            plain_peer: subprocess.Popen[str]) -> None:
    assert plain_peer.stdin is not None and plain_peer.stdout is not None
    client = dds.ServiceClient(builder, DOMAIN, "/plain/set", "std_srvs/srv/SetBool")
    served: list[Any] = []

    def handle(request: Any) -> Any:
        served.append(request)
        return server.response_of(request, success=True, message="served")

    server = dds.ServiceServer(builder, DOMAIN, "/plain/serve", "std_srvs/srv/Trigger", handle)
    called: list[Any] = []
    calls = dds.ServiceServer(builder, DOMAIN, "/plain/call", "umlbot_msgs/srv/CallFeature", called.append)
    try:
        for seq, data in ((1, True), (2, False)):
            request = client.request()
            request.data = data
            reply = client.call(request, 10.0)
            assert (reply.rmw_guid, reply.rmw_seq) == (client.guid, seq)
            assert (reply.success, reply.message) == (not data, f"seq {seq}")
            printed = plain_peer.stdout.readline().split()
            assert printed == ["request", f"{client.guid:x}", str(seq), str(data)]
        plain_peer.stdin.write("garbage\ncall\n")
        plain_peer.stdin.flush()
        assert plain_peer.stdout.readline().strip() == "garbage 0", "the peer's DDS took it"
        assert plain_peer.stdout.readline().strip() == "reply True served"
        assert [(r.rmw_guid, r.rmw_seq) for r in served] == [(0xABCDEF, 41)]
        assert server.served == 1
        deadline = time.monotonic() + 5
        while calls.bad == 0 and time.monotonic() < deadline:
            time.sleep(0.02)
        assert (calls.bad, called) == (1, []), "the garbage came and was refused, not handled"
    finally:
        client.close()
        server.close()
        calls.close()
