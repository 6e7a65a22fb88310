"""The recorder: takes what the robot does without ever making it wait, and writes it in a thread.

Producers (the bus connection's network thread, the orchestrator's trace listener, the sim
sampler) only append a tuple to a bounded queue (a deque: no lock, no wake-up, no I/O, no
parsing); when the queue is full the item is dropped and counted (`dropped`), the robot goes on.
The writer thread wakes every `BATCH_S` and takes what has come meanwhile, in one go (a wake-up
per message cost more CPU than writing it: docs/performance.md, Recording). It does the rest:
decodes the MQTT payloads (calls paired with their replies by `MonitorState`, the same decoder as
the monitor's), makes the ROS 2 messages, serialises them to CDR once (trace events and calls
straight from their values: `cdr.py`) and hands them to every sink (the MCAP file, the live
Foxglove server). A sink that fails (the disk is
full) ends itself cleanly (`McapBag`); the recorder goes on for the other sinks and the robot
never notices.
"""

from __future__ import annotations

import contextlib
import threading
import time
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Literal, Protocol, cast

from pydantic_core import from_json

from umlbot.base import rosmsg
from umlbot.base.logs import get_logger
from umlbot.monitor import MonitorEvent, MonitorState
from umlbot.record.cdr import feature_call, trace_event
from umlbot.record.messages import (
    CALL,
    JOINTS,
    MARKERS,
    ORCHESTRATOR,
    POSE,
    RANGE,
    SIGNAL,
    STATE,
    STATUS,
    TRACE,
    Builder,
    Topics,
    to_ns,
)
from umlbot.services.bus import BrokerSettings, BusConnection, Message

log = get_logger(__name__)

#: items waiting for the writer thread at most; more are dropped (and counted).
DEFAULT_MAX_QUEUE = 100_000
#: the writer thread looks after the sinks (chunk flushes, unanswered calls) this often.
TICK_S = 0.2
#: the writer thread takes the queued items this often (seconds): a live view lags by at most that
BATCH_S = 0.02

ClockName = Literal["sim", "wall"]


class Sink(Protocol):
    """Where the recorder's messages go: an MCAP file, a live server."""

    def write_cdr(self, topic: str, msgtype: str, data: bytes | memoryview, stamp_ns: int) -> None: ...

    def tick(self) -> None: ...

    def close(self) -> None: ...


@dataclass(frozen=True)
class RecordStats:
    """How a recording went: messages made, items dropped (queue full), why a sink failed."""

    messages: int
    dropped: int
    failed: str | None


@dataclass(slots=True)
class _Call:
    """The fields of a call's `MonitorEvent` the recorder reads."""

    time: float
    component: str | None
    feature: str | None
    id: str | None
    args: list[Any] | None
    ok: bool | None
    value: Any
    error: str | None
    latency_ms: float | None
    type: str = "call"


class _CallPairs(MonitorState):
    """The monitor's pairing of requests and replies (its time-outs, its handling of malformed
    messages), without what only the monitor shows: its per-feature latency sketches and its
    list of recent calls, and without a pydantic `MonitorEvent` for each paired call (`_Call`
    holds the same values): about half of the recorder's CPU for a call."""

    def _record_call(self, event: MonitorEvent) -> MonitorEvent:
        return event

    def _finish(self, pending: Any, call_id: str, *, at: float, ok: bool, value: Any,
                error: str | None, latency_ms: float | None) -> MonitorEvent:
        call = _Call(at, pending.component, pending.feature, call_id, pending.args, ok, value, error,
                     latency_ms)
        return cast(MonitorEvent, call)  # read only by `Recorder._call_event`


class Recorder:
    """Writes the robot's traffic to `sinks` from its own thread (see the module docstring).

    `now()` is the run's clock in seconds (`clock` says which: "sim" time in the sim, unix "wall"
    time on a robot): MQTT messages are stamped with it when they arrive; trace events carry their
    own times. A call's latency is wall time in both (sim time stands still during a call).
    """

    def __init__(self, robot: str, sinks: list[Sink], now: Callable[[], float] = time.time,
                 max_queue: int = DEFAULT_MAX_QUEUE, clock: ClockName = "wall") -> None:
        self.robot = robot
        self.topics = Topics(robot)
        self.store = rosmsg.typestore("record")
        self.build = Builder(self.store)
        self.sinks = list(sinks)
        self.now = now
        self.clock = clock
        self._queue: deque[tuple[Any, ...]] = deque()
        self._max_queue = max_queue
        self._calls = _CallPairs()
        self._trace_topic, self._calls_topic = self.topics.trace, self.topics.calls
        self._viewers = self._trace_viewers  # a sink shows trace events; noted again every batch
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name="umlbot-recorder", daemon=True)
        self._connection: BusConnection | None = None
        self._with_trace = False  # record the trace topic too (`listen(trace=True)`)
        self._closed = False
        #: messages handed to the sinks
        self.messages = 0
        #: items dropped because the queue was full
        self.dropped = 0
        #: set (by the writer thread, after everything before it is written) when the robot's
        #: orchestrator, seen starting or running, says stopped, failed or offline
        self.orchestrator_ended = threading.Event()
        self._orchestrator_ran = False
        self._thread.start()

    # -- producers: never block -----------------------------------------------------------------

    def _offer(self, item: tuple[Any, ...]) -> None:
        if len(self._queue) < self._max_queue:
            self._queue.append(item)  # atomic (the GIL); the writer thread polls
        else:
            self.dropped += 1

    def on_message(self, message: Message) -> None:
        """A bus message of the robot (the bus dispatcher calls it)."""
        self._offer(("mqtt", message.topic, message.payload, self.now(), time.time()))

    def on_trace(self, event: dict[str, Any]) -> None:
        """One trace event of the orchestrator (its `trace_listener`)."""
        self._offer(("trace", event))

    def offer(self, *item: Any) -> None:
        """A sample of the sim: ("pose", t, x, y, heading), ("sonar", t, cm, x0, y0, angle), ("motors", t,
        (duty_left, duty_right), (speed_left, speed_right)) or ("track", t, walls, goal)."""
        self._offer(item)

    def listen(self, settings: BrokerSettings, *, trace: bool, timeout: float | None = 10.0) -> None:
        """Subscribe to `umlbot/<robot>/#` (its trace topic too only when `trace`: in `umlbot sim`
        and `umlbot run` the trace comes from the orchestrator itself, complete)."""
        self._with_trace = trace
        connection = BusConnection(settings, "recorder", robot=self.robot, read_ahead=True)
        # on the network thread itself: `on_message` only appends to the queue (never blocks), so
        # the dispatcher thread's hand-over (a socket write and read a message) is not needed
        connection.subscribe_inline(f"umlbot/{self.robot}/#", self.on_message)
        self._connection = connection
        connection.start(timeout)
        if timeout is not None:
            connection.wait_subscribed(timeout)

    def stop_listening(self) -> None:
        """Unsubscribe and disconnect from the broker (before it stops); idempotent."""
        connection, self._connection = self._connection, None
        if connection is not None:
            with contextlib.suppress(Exception):
                connection.close()

    # -- the writer thread ----------------------------------------------------------------------

    def _run(self) -> None:
        items, stop = self._queue, self._stop
        next_tick = time.monotonic() + TICK_S
        while True:
            stopping = stop.is_set()  # before taking the items: what came before the stop is written
            self._viewers = self._trace_viewers
            while items:
                item = items.popleft()
                try:
                    self._handle(item)
                except Exception as exc:  # a recording must never take anything down
                    log.warning("recording: item skipped", kind=item[0], error=str(exc))
            if stopping:
                return
            if time.monotonic() >= next_tick:
                next_tick = time.monotonic() + TICK_S
                self._tick()
            stop.wait(BATCH_S)

    def _tick(self) -> None:
        for event in self._calls.expire(time.time()):
            self._call_event(event, None)
        for sink in self.sinks:
            try:
                sink.tick()
            except Exception as exc:
                log.warning("recording: sink failed", sink=type(sink).__name__, error=str(exc))

    def _emit(self, topic: str, msgtype: str, message: Any, stamp_ns: int) -> None:
        """A ROS 2 message object: serialised to CDR once, then as `_write`."""
        self._write(topic, msgtype, self.store.serialize_cdr(message, msgtype), stamp_ns)

    def _handle(self, item: tuple[Any, ...]) -> None:
        kind = item[0]
        if kind == "mqtt":
            self._mqtt(item[1], item[2], item[3], item[4])
        elif kind == "trace":
            self._trace(item[1])
        else:
            self._sample(item)

    def _sample(self, item: tuple[Any, ...]) -> None:
        """A sample of the sim: its message, and to the sinks that draw a scene (`sample`)."""
        kind, build, topics = item[0], self.build, self.topics
        if kind == "pose":
            _, at, x, y, heading = item
            self._emit(topics.pose, POSE, build.pose(at, x, y, heading), to_ns(at))
        elif kind == "sonar":
            at, cm = item[1], item[2]
            self._emit(topics.sonar, RANGE, build.sonar(at, cm), to_ns(at))
        elif kind == "motors":
            _, at, duty, speed = item
            self._emit(topics.motors, JOINTS, build.motors(at, duty, speed), to_ns(at))
        elif kind == "track":
            _, at, walls, goal = item
            self._emit(topics.track, MARKERS, build.track(at, walls, goal), to_ns(at))
        for sink in self.sinks:
            sample = getattr(sink, "sample", None)
            if sample is not None:
                try:
                    sample(item)
                except Exception as exc:
                    log.warning("recording: sink failed", sink=type(sink).__name__, error=str(exc))

    def _write(self, topic: str, msgtype: str, data: bytes | memoryview, stamp_ns: int) -> None:
        """As `_emit`, for a message already in CDR."""
        self.messages += 1
        for sink in self.sinks:
            try:
                sink.write_cdr(topic, msgtype, data, stamp_ns)
            except Exception as exc:
                log.warning("recording: sink failed", sink=type(sink).__name__, error=str(exc))

    def _trace(self, event: dict[str, Any]) -> None:
        if not self._viewers:  # straight to CDR, without the message object (cdr.py)
            data, stamp_ns = trace_event(event)
            self._write(self._trace_topic, TRACE, data, stamp_ns)
            return
        message = self.build.trace(event)
        self._emit(self.topics.trace, TRACE, message, to_ns(message.end))
        for sink in self.sinks:  # a live view also shows the trace as log lines
            on_trace = getattr(sink, "on_trace", None)
            if on_trace is not None:
                try:
                    on_trace(message)
                except Exception as exc:
                    log.warning("recording: sink failed", sink=type(sink).__name__, error=str(exc))

    def _mqtt(self, topic: str, payload: bytes, at: float, wall: float) -> None:
        levels = topic.split("/")[2:]  # after umlbot/<robot>/
        if not levels:
            return
        head, build, topics = levels[0], self.build, self.topics
        if head == "_reply" or (len(levels) >= 3 and levels[1] == "call"):
            for event in self._calls.observe(topic, payload, wall):
                self._call_event(event, at)
            return
        if not payload:  # a cleared retained message
            return
        data = _json(payload)
        if head == "orchestrator" and len(levels) == 2:
            if levels[1] == "trace":
                if self._with_trace:
                    for event in data if isinstance(data, list) else [data]:
                        if isinstance(event, dict):
                            self._trace(event)
            elif levels[1] == "status":
                self._calls.observe(topic, payload, wall)  # it learns the run's call time-out
                message = build.orchestrator(at, data)
                self._emit(topics.orchestrator, ORCHESTRATOR, message, to_ns(at))
                if message.state in ("starting", "running"):
                    self._orchestrator_ran = True
                elif message.state in ("stopped", "failed", "offline") and self._orchestrator_ran:
                    self.orchestrator_ended.set()
        elif head == "signal" and len(levels) >= 2:
            name = "/".join(levels[1:])
            self._emit(topics.signals, SIGNAL, build.signal(at, name, data), to_ns(at))
        elif len(levels) == 2 and levels[1] == "status":
            self._emit(topics.status(head), STATUS, build.status(at, head, data), to_ns(at))
        elif len(levels) == 2 and levels[1] == "state":
            self._emit(topics.state(head), STATE, build.state(at, head, data), to_ns(at))

    def _call_event(self, event: Any, at: float | None) -> None:
        """Record a call event of `MonitorState` (wall times); `at`: the run's time of the message
        that finished it (None: a call that expired unanswered, now)."""
        if event.type != "call" or event.component is None or event.feature is None:
            return
        if self.clock == "wall":  # stamped when requested: the reply's time less the latency
            at = event.time - (event.latency_ms or 0.0) / 1000.0
        elif at is None:
            at = self.now()
        data, stamp_ns = feature_call(at, event.component, event.feature, event.id, event.args, event.ok,
                                      event.value, event.error, event.latency_ms)
        self._write(self._calls_topic, CALL, data, stamp_ns)

    # -- the end --------------------------------------------------------------------------------

    def close(self, timeout: float = 10.0) -> RecordStats:
        """Stop listening, write what is queued (for at most `timeout` s), close the sinks."""
        if not self._closed:
            self._closed = True
            self.stop_listening()
            self._stop.set()
            self._thread.join(timeout)
            if self._thread.is_alive():
                log.warning("recording: the writer did not finish in time", pending=len(self._queue))
            for sink in self.sinks:
                try:
                    sink.close()
                except Exception as exc:
                    log.warning("recording: sink failed to close", sink=type(sink).__name__, error=str(exc))
            if self.dropped:
                log.warning("recording: items dropped (the writer fell behind)", dropped=self.dropped)
        return self.stats

    @property
    def _trace_viewers(self) -> bool:
        """A sink shows trace events as they come (`on_trace`: it needs the message object)."""
        return any(getattr(sink, "on_trace", None) is not None for sink in self.sinks)

    @property
    def stats(self) -> RecordStats:
        failed = next((f for f in (getattr(s, "failed", None) for s in self.sinks) if f), None)
        return RecordStats(self.messages, self.dropped, failed)


def _json(payload: bytes) -> Any:
    try:
        return from_json(payload)
    except ValueError:
        return payload.decode("utf-8", "replace")


def open_file_recorder(path: str | Path, robot: str, clock: ClockName, now: Callable[[], float],
                       model: str | None = None, extra_sinks: list[Sink] | None = None) -> Recorder:
    """A recorder writing the rosbag2 MCAP file `path`; its metadata says which `clock` stamps it."""
    from umlbot import __version__
    from umlbot.record.bag import McapBag

    custom = {"umlbot.clock": clock, "umlbot.robot": robot, "umlbot.version": __version__}
    if model:
        custom["umlbot.model"] = model
    bag = McapBag(path, custom_data=custom)
    return Recorder(robot, [bag, *(extra_sinks or [])], now, clock=clock)


__all__ = ["BATCH_S", "CALL", "DEFAULT_MAX_QUEUE", "RecordStats", "Recorder", "Sink", "open_file_recorder"]
