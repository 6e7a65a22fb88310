"""What the monitor knows about a robot, built from the MQTT messages it sees (SPEC §3).

`MonitorState.observe(topic, payload, at)` turns one message under `umlbot/<robot>/` into zero or
more `MonitorEvent`s and updates the picture the live view draws: availability per component,
the last calls with their latency (a request on `…/call/<feature>` paired by `reply_to` and `id`
with its reply), the node each lane executes, and per-action counts with p50/p99 durations.
Nothing here touches the network; the same state is fed live from the bus or from a trace file.

Memory is bounded whatever the run's length and whatever names come over the wire: each table
keeps at most `MAX_ROWS` rows (`umlbot.base.bounded.RecentDict`: the row untouched for longest goes
first, counted in `dropped_rows`), the pending calls at most `MAX_PENDING_CALLS`, and a row's
durations are a DDSketch (`ddsketch`, relative accuracy 1 %, at most `SKETCH_BINS` bins: a few
kilobytes, 29 kB for durations spread from 1 µs to 10 s) instead of the samples.

Wire input is untrusted: a payload that is not JSON where JSON is needed, nested deeper than
`pydantic_core.from_json` allows (about 200 levels), not UTF-8 or of the wrong shape is skipped and
counted in `malformed`; the first one logs one warning, the rest are only counted.
"""

from __future__ import annotations

import math
from collections import Counter, deque
from dataclasses import dataclass, field
from typing import Any, Literal

from ddsketch import LogCollapsingLowestDenseDDSketch
from pydantic import BaseModel, ConfigDict, ValidationError
from pydantic_core import from_json

from umlbot.base.bounded import MAX_ROWS, RecentDict
from umlbot.base.logs import get_logger
from umlbot.services.bus import ENVELOPE_KEYS, CallRequest, Reply, TraceEvent, dumps

log = get_logger(__name__)

EventType = Literal["availability", "call", "state", "signal", "trace", "orchestrator", "exit"]

#: trace node kinds that do work (their durations are worth a percentile); a datastore counts
#: when it is set from a call (its label has parentheses), not from a constant.
TIMED_KINDS = frozenset({"action", "send", "accept"})
#: a request without a reply for this long is reported as unanswered, unless the orchestrator's
#: retained status says its own time-out (`call_timeout_s`) or the monitor was given one.
DEFAULT_CALL_TIMEOUT_S = 5.0
#: relative accuracy of the percentiles (the page's are as accurate: studio/web/src/model/durations.ts)
RELATIVE_ACCURACY = 0.01
#: bins of one row's sketch at most (the lowest collapse beyond): 1 µs to 24 h at 1 % takes 1270
SKETCH_BINS = 2048
MAX_PENDING_CALLS = 10_000
#: how `pydantic_core.from_json` says that JSON is nested too deeply (then it is malformed, not text).
TOO_DEEP = "recursion limit exceeded"


class MonitorEvent(BaseModel):
    """One thing that happened on the robot, as printed by `umlbot monitor --json` (one a line)."""

    model_config = ConfigDict(extra="forbid")

    type: EventType
    time: float  # unix seconds: when the monitor saw it (a trace event: when the node ended)
    robot: str
    topic: str | None = None
    component: str | None = None
    feature: str | None = None
    state: str | None = None  # availability ("online"/"offline") or the orchestrator's state
    impl: str | None = None
    driver: str | None = None  # availability: the driver the service runs (its status says it)
    args: list[Any] | None = None
    id: str | None = None
    ok: bool | None = None
    value: Any = None
    error: str | None = None
    latency_ms: float | None = None
    lane: str | None = None
    node: str | None = None
    kind: str | None = None
    duration_ms: float | None = None
    level: str | None = None
    detail: str | None = None
    seq: int | None = None  # a trace event's number in its orchestrator run
    payload: Any = None

    def line(self) -> str:
        """The compact JSON line (fields that are None left out)."""
        return self.model_dump_json(exclude_none=True)


@dataclass
class Stats:
    """Count, errors and the durations (ms) of one action or feature, in bounded memory: p50 and
    p99 over every sample, within 1 % (NaN before the first)."""

    label: str
    count: int = 0
    errors: int = 0
    durations: LogCollapsingLowestDenseDDSketch = field(
        default_factory=lambda: LogCollapsingLowestDenseDDSketch(RELATIVE_ACCURACY, SKETCH_BINS))

    def add(self, duration_ms: float | None, failed: bool = False) -> None:
        self.count += 1
        if failed:
            self.errors += 1
        if duration_ms is not None and math.isfinite(duration_ms):
            self.durations.add(max(0.0, duration_ms))

    def quantile(self, fraction: float) -> float:
        """The duration (ms) below which `fraction` of the samples lie, within 1 %; NaN when none."""
        value = self.durations.get_quantile_value(fraction)
        return math.nan if value is None else float(value)

    @property
    def p50(self) -> float:
        return self.quantile(0.50)

    @property
    def p99(self) -> float:
        return self.quantile(0.99)


@dataclass
class Availability:
    """The last status a component published; `since` (unix seconds) is when it entered that
    state: the `since` its status says (an online status says when the service came online),
    else when the monitor first saw the state (the last will, `{"state": "offline"}`, says none)."""

    state: str
    impl: str | None
    since: float
    driver: str | None = None  # the driver the status says the service runs (`auto` resolved)


@dataclass
class LaneNow:
    """The node a lane executed last (trace events arrive when a node ends)."""

    node: str
    kind: str
    detail: str | None
    at: float
    error: str | None = None


@dataclass
class _Pending:
    robot: str
    component: str
    feature: str
    args: list[Any]
    at: float
    topic: str
    timeout_s: float | None = None  # the caller's own time-out, when its request says it


def split_topic(topic: str) -> tuple[str, list[str]] | None:
    """(robot, levels after `umlbot/<robot>/`) or None for a topic outside umlbot."""
    parts = topic.split("/")
    if len(parts) < 3 or parts[0] != "umlbot":
        return None
    return parts[1], parts[2:]


class MonitorState:
    """The robot as the monitor sees it; feed it messages, read its tables, print its events."""

    def __init__(self, call_timeout_s: float | None = None, recent: int = 20,
                 fallback_call_timeout_s: float = DEFAULT_CALL_TIMEOUT_S) -> None:
        #: the time-out given (`umlbot monitor --call-timeout`); None: the one the robot's
        #: orchestrator announces in its status, else `fallback_call_timeout_s` (the studio passes
        #: the model's `call_timeout_s`).
        self.call_timeout_s = call_timeout_s
        self.fallback_call_timeout_s = fallback_call_timeout_s
        #: the time-out each robot's orchestrator says it uses (its retained status).
        self.robot_call_timeouts: RecentDict[str, float] = RecentDict(MAX_ROWS)
        self.availability: RecentDict[tuple[str, str], Availability] = RecentDict(MAX_ROWS)
        self.orchestrator: RecentDict[str, str] = RecentDict(MAX_ROWS)
        self.lanes: RecentDict[tuple[str, str], LaneNow] = RecentDict(MAX_ROWS)
        self.actions: RecentDict[tuple[str, str, str], Stats] = RecentDict(MAX_ROWS)
        self.features: RecentDict[tuple[str, str, str], Stats] = RecentDict(MAX_ROWS)
        self.recent_calls: deque[MonitorEvent] = deque(maxlen=recent)
        self.recent_events: deque[MonitorEvent] = deque(maxlen=recent)
        self.messages = 0
        #: messages (or trace events inside a batch) skipped because they were malformed.
        self.malformed = 0
        self._pending: dict[tuple[str, str], _Pending] = {}
        self._reply_topics: Counter[str] = Counter()  # reply_to topics of the pending calls

    # -- input ----------------------------------------------------------------------------------

    def observe(self, topic: str, payload: bytes, at: float) -> list[MonitorEvent]:
        """Take one MQTT message seen at unix time `at`; return the events it makes.

        Never raises for what came over the wire: a malformed message is counted and skipped.
        """
        try:
            return self._observe(topic, payload, at)
        except (ValueError, TypeError, RecursionError) as exc:  # ValidationError is a ValueError
            self._skip(topic, exc)
            return []

    def _skip(self, topic: str, problem: Exception | str) -> None:
        self.malformed += 1
        if self.malformed == 1:
            text = problem if isinstance(problem, str) else first_problem(problem)
            log.warning("malformed message skipped (further ones are only counted)", topic=topic,
                        problem=text[:200])

    def _observe(self, topic: str, payload: bytes, at: float) -> list[MonitorEvent]:
        where = split_topic(topic)
        if where is None:
            if topic in self._reply_topics:  # a caller chose a reply topic outside umlbot/
                self.messages += 1
                return self._on_reply(topic, payload, at)
            return []
        self.messages += 1
        robot, levels = where
        events: list[MonitorEvent] = []
        if levels[0] == "_reply" or topic in self._reply_topics:
            events += self._on_reply(topic, payload, at)
        elif levels[0] == "signal" and len(levels) >= 2:
            events.append(MonitorEvent(type="signal", time=at, robot=robot, topic=topic,
                                       feature="/".join(levels[1:]), payload=_json_or_text(payload)))
        elif levels[0] == "orchestrator" and len(levels) == 2:
            events += self._on_orchestrator(robot, levels[1], topic, payload, at)
        elif len(levels) >= 3 and levels[1] == "call":
            events += self._on_request(robot, levels[0], "/".join(levels[2:]), topic, payload, at)
        elif len(levels) == 2 and levels[1] == "status":
            events += self._on_status(robot, levels[0], topic, payload, at)
        elif len(levels) == 2 and levels[1] == "state":
            events.append(MonitorEvent(type="state", time=at, robot=robot, topic=topic,
                                       component=levels[0], payload=_json_or_text(payload)))
        for event in events:
            if event.type != "call":
                self.recent_events.append(event)
        return events

    def observe_trace(self, trace: TraceEvent, robot: str, topic: str | None = None) -> MonitorEvent:
        """Take one trace event (from the bus or a trace file) and return its monitor event."""
        now = LaneNow(trace.node, trace.kind, trace.detail, trace.end, trace.error)
        self.lanes[(robot, trace.lane)] = now
        if trace.kind in TIMED_KINDS or (trace.kind == "datastore" and "(" in (trace.detail or "")):
            label = trace.detail or trace.node
            stats = self.actions.touch((robot, trace.lane, trace.node), lambda: Stats(label))
            stats.add(trace.duration_ms, failed=trace.error is not None)
        return MonitorEvent(
            type="trace", time=trace.end, robot=robot, topic=topic, lane=trace.lane, node=trace.node,
            kind=trace.kind, duration_ms=trace.duration_ms, value=trace.value, error=trace.error,
            level=trace.level, detail=trace.detail, seq=trace.seq,
        )

    def call_timeout(self, robot: str) -> float:
        """Seconds after which a call of `robot` without a reply is reported as unanswered, unless
        its request says its own (`timeout_s`): the time-out given, else the one its orchestrator
        announced, else the fallback."""
        if self.call_timeout_s is not None:
            return self.call_timeout_s
        return self.robot_call_timeouts.get(robot, self.fallback_call_timeout_s)

    def expire(self, now: float) -> list[MonitorEvent]:
        """Report the calls that got no reply within their time-out as failed (`error` says so):
        the caller's own when the request says it (the orchestrator's fail-safe stop calls wait
        1 s, its other calls the run's `call_timeout_s`), else `call_timeout(robot)`.

        The event keeps the request's time (it is listed where the call was made, not when the
        monitor gave up on it) and has no latency.
        """
        late = [(key, timeout) for key, p in self._pending.items()
                if now - p.at > (timeout := p.timeout_s or self.call_timeout(p.robot))]
        events = []
        for key, timeout in late:
            pending = self._take(key)
            assert pending is not None
            events.append(self._finish(pending, key[1], at=pending.at, ok=False, value=None,
                                       error=f"no reply within {timeout:g} s", latency_ms=None))
        return events

    @property
    def dropped_rows(self) -> int:
        """Rows the tables dropped to stay within `MAX_ROWS` (names enough for a thousand robots)."""
        return sum(table.dropped for table in (self.robot_call_timeouts, self.availability, self.orchestrator,
                                               self.lanes, self.actions, self.features))

    @property
    def pending_calls(self) -> int:
        """Requests seen whose reply has not arrived yet."""
        return len(self._pending)

    # -- message kinds --------------------------------------------------------------------------

    def _on_request(self, robot: str, component: str, feature: str, topic: str, payload: bytes,
                    at: float) -> list[MonitorEvent]:
        try:
            data = from_json(payload) if payload else None
        except ValueError:
            return [self._record_call(MonitorEvent(
                type="call", time=at, robot=robot, topic=topic, component=component, feature=feature,
                ok=False, error="bad_json: the request is not JSON"))]
        if isinstance(data, dict) and data and set(data) <= ENVELOPE_KEYS:
            try:
                request = CallRequest.model_validate(data)
            except ValidationError:
                return [self._record_call(MonitorEvent(
                    type="call", time=at, robot=robot, topic=topic, component=component, feature=feature,
                    ok=False, error="bad_request: not a valid request envelope"))]
            if request.reply_to and request.id is not None:
                if len(self._pending) >= MAX_PENDING_CALLS:
                    self._take(next(iter(self._pending)))
                key = (request.reply_to, str(request.id))
                self._take(key)  # a repeated id replaces the older request
                self._reply_topics[request.reply_to] += 1
                self._pending[key] = _Pending(robot, component, feature, request.args, at, topic,
                                              request.timeout_s)
                return []
            args: list[Any] = request.args
        else:
            args = data if isinstance(data, list) else [data]
        # fire-and-forget: no reply will come
        return [self._record_call(MonitorEvent(
            type="call", time=at, robot=robot, topic=topic, component=component, feature=feature,
            args=args, detail="fire-and-forget"))]

    def _on_reply(self, topic: str, payload: bytes, at: float) -> list[MonitorEvent]:
        try:
            reply = Reply.model_validate_json(payload)
        except ValidationError as exc:
            self._skip(topic, exc)
            return []
        key = (topic, str(reply.id))
        pending = self._take(key)
        if pending is None:
            return []  # a reply to a call made before the monitor started
        error = f"{reply.error.code}: {reply.error.message}" if reply.error is not None else None
        return [self._finish(pending, key[1], at=at, ok=reply.ok, value=reply.value, error=error,
                             latency_ms=round((at - pending.at) * 1000.0, 3))]

    def _take(self, key: tuple[str, str]) -> _Pending | None:
        """Remove a pending call (and its count on its reply topic)."""
        pending = self._pending.pop(key, None)
        if pending is not None:
            self._reply_topics[key[0]] -= 1
            if self._reply_topics[key[0]] <= 0:
                del self._reply_topics[key[0]]
        return pending

    def _finish(self, pending: _Pending, call_id: str, *, at: float, ok: bool, value: Any,
                error: str | None, latency_ms: float | None) -> MonitorEvent:
        return self._record_call(MonitorEvent(
            type="call", time=at, robot=pending.robot, topic=pending.topic, component=pending.component,
            feature=pending.feature, args=pending.args, id=call_id, ok=ok, value=value, error=error,
            latency_ms=latency_ms))

    def _record_call(self, event: MonitorEvent) -> MonitorEvent:
        assert event.component is not None and event.feature is not None
        label = f"{event.component}.{event.feature}"
        stats = self.features.touch((event.robot, event.component, event.feature), lambda: Stats(label))
        stats.add(event.latency_ms, failed=event.ok is False)
        recent = self.recent_calls
        if recent and recent[-1].time > event.time:  # an expired call: listed at its request's time
            place = len(recent)
            while place > 0 and recent[place - 1].time > event.time:
                place -= 1
            if len(recent) == recent.maxlen:
                if place == 0:
                    return event  # older than every call listed
                recent.popleft()
                place -= 1
            recent.insert(place, event)
        else:
            recent.append(event)
        return event

    def _on_status(self, robot: str, component: str, topic: str, payload: bytes,
                   at: float) -> list[MonitorEvent]:
        data = _json_or_text(payload)
        if not payload:  # a cleared retained status
            self.availability.pop((robot, component), None)
            return []
        state = (_text(data.get("state")) if isinstance(data, dict) else None) or "unknown"
        impl = _text(data.get("impl")) if isinstance(data, dict) else None
        since = _since(data.get("since")) if isinstance(data, dict) else None
        driver = _text(data.get("driver")) if isinstance(data, dict) and state == "online" else None
        previous = self.availability.get((robot, component))
        if previous is not None:
            self.availability.move_to_end((robot, component))  # still there: not the oldest row
        if previous is not None and previous.state == state and driver in (None, previous.driver):
            previous.impl = impl or previous.impl
            if since is not None:  # e.g. a service that restarted and is online again
                previous.since = since
            return []
        self.availability[(robot, component)] = Availability(state, impl, at if since is None else since,
                                                             driver)
        return [MonitorEvent(type="availability", time=at, robot=robot, topic=topic, component=component,
                             state=state, impl=impl, driver=driver)]

    def _on_orchestrator(self, robot: str, leaf: str, topic: str, payload: bytes,
                         at: float) -> list[MonitorEvent]:
        if leaf == "trace":
            events = []
            for item in trace_items(from_json(payload)):
                try:
                    trace = TraceEvent.model_validate(item)
                except ValidationError as exc:
                    self._skip(topic, exc)
                    continue
                events.append(self.observe_trace(trace, robot, topic))
            return events
        data = _json_or_text(payload)
        if leaf == "status":
            if not payload:
                return []
            state = (_text(data.get("state")) if isinstance(data, dict) else _text(data)) or "unknown"
            self.orchestrator[robot] = state
            timeout = data.get("call_timeout_s") if isinstance(data, dict) else None
            if isinstance(timeout, int | float) and not isinstance(timeout, bool) and 0 < timeout < math.inf:
                self.robot_call_timeouts[robot] = float(timeout)
            reason = _text(data.get("reason")) if isinstance(data, dict) else None
            return [MonitorEvent(type="orchestrator", time=at, robot=robot, topic=topic, state=state,
                                 detail=reason)]
        if leaf == "exit":
            return [MonitorEvent(type="exit", time=at, robot=robot, topic=topic, payload=data)]
        return []


def trace_items(data: Any) -> list[Any]:
    """The events of one trace message: a single `TraceEvent` object or a JSON array of them."""
    return data if isinstance(data, list) else [data]


def _since(value: Any) -> float | None:
    """A status's `since` when it is a plausible unix time (a finite number > 0), else None."""
    if isinstance(value, int | float) and not isinstance(value, bool) and 0 < value < math.inf:
        return float(value)
    return None


def _text(value: Any) -> str | None:
    """A wire value meant to be a short text: strings as they are, other JSON as JSON, null None."""
    if value is None or isinstance(value, str):
        return value
    return dumps(value)


def first_problem(exc: Exception) -> str:
    """What is wrong, in one line (the first error of a ValidationError)."""
    if isinstance(exc, ValidationError):
        first = exc.errors()[0]
        where = ".".join(str(p) for p in first["loc"])
        return f"{where}: {first['msg']}" if where else str(first["msg"])
    if isinstance(exc, RecursionError):
        return "nested too deeply"
    return str(exc) or type(exc).__name__


def _json_or_text(payload: bytes) -> Any:
    """The payload as JSON when it is JSON, else as text.

    Raises ValueError (the message is malformed) for JSON nested too deeply and for bytes that
    are not UTF-8.
    """
    try:
        return from_json(payload)
    except ValueError as exc:
        if TOO_DEEP in str(exc):
            raise
        return payload.decode("utf-8")
