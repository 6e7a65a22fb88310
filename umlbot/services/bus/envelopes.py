"""Every JSON payload on the bus, as pydantic models, in one module (SPEC §3).

Requests, replies and error bodies; component availability (`Status`); and the orchestrator's
own payloads (`TraceEvent`, `OrchestratorStatus`, `Heartbeat`, `ExitRequest`). `to_payload`
turns anything publishable into the UTF-8 JSON bytes that go on the wire; `parse_json` reads
them back.
"""

from __future__ import annotations

import json
from typing import Any, Final, Literal

from pydantic import BaseModel, ConfigDict, Field

from umlbot.base.files import loads_json

#: The stable error codes of an error reply (`Reply.error.code`).
ErrorCode = Literal[
    "bad_json",  # the payload is not UTF-8 JSON
    "bad_request",  # JSON, but not a valid request envelope
    "bad_args",  # wrong number or type of arguments
    "unknown_feature",  # the component has no such feature
    "out_of_range",  # an argument outside the feature's range
    "payload_too_large",  # the request is bigger than the service accepts
    "driver_error",  # the hardware driver failed
    "internal",  # a bug in the service; details only in its log
]
ERROR_CODES: Final[tuple[str, ...]] = (
    "bad_json",
    "bad_request",
    "bad_args",
    "unknown_feature",
    "out_of_range",
    "payload_too_large",
    "driver_error",
    "internal",
)

#: Keys that make a JSON object a request envelope rather than a bare argument.
ENVELOPE_KEYS: Final[frozenset[str]] = frozenset({"id", "reply_to", "args", "timeout_s"})


class CallRequest(BaseModel):
    """A call envelope: `{"id": "...", "reply_to": "<topic>", "args": [...], "timeout_s": 2.0}`.

    Without `reply_to` (and without an MQTT 5 Response Topic) the call is fire-and-forget.
    `timeout_s` (optional) says how long the caller waits for the reply: the service ignores it,
    a monitor reports the call as unanswered after it (the caller's own time-out, not a guess).
    """

    model_config = ConfigDict(extra="forbid")

    id: str | int | None = None
    reply_to: str | None = Field(default=None, min_length=1)
    args: list[Any] = Field(default_factory=list)
    timeout_s: float | None = Field(default=None, gt=0, allow_inf_nan=False)


def is_timeout(value: Any) -> bool:
    """Whether `value` is a valid `timeout_s` of a request: a finite number of seconds > 0."""
    return (isinstance(value, int | float) and not isinstance(value, bool)
            and 0 < value < float("inf"))


class ErrorBody(BaseModel):
    """Why a call failed: a stable `code` (see `ErrorCode`) and a human-readable message."""

    code: str
    message: str


class Reply(BaseModel):
    """The answer to a call: `{"id", "ok": true, "value"}` or `{"id", "ok": false, "error"}`."""

    id: str | int | None = None
    ok: bool
    value: Any = None
    error: ErrorBody | None = None

    @classmethod
    def success(cls, request_id: str | int | None, value: Any) -> Reply:
        return cls(id=request_id, ok=True, value=value)

    @classmethod
    def failure(cls, request_id: str | int | None, code: str, message: str) -> Reply:
        return cls(id=request_id, ok=False, error=ErrorBody(code=code, message=message))

    def wire(self) -> dict[str, Any]:
        """The JSON object on the wire: `value` only on success, `error` only on failure."""
        if self.ok:
            return {"id": self.id, "ok": True, "value": self.value}
        assert self.error is not None
        return {"id": self.id, "ok": False, "error": {"code": self.error.code, "message": self.error.message}}


class Status(BaseModel):
    """Retained availability of a component (`…/<Component>/status`).

    The broker publishes `{"state": "offline"}` (the last will) when the service vanishes.
    """

    model_config = ConfigDict(extra="allow")

    state: Literal["online", "offline"]
    impl: str | None = None
    features: list[str] = Field(default_factory=list)
    #: a random name of the serving process (not its client id, which nobody else may learn)
    instance: str | None = None
    since: float | None = None  # unix time the service came online
    #: the driver the service runs the component with (`auto` resolved, e.g. "mock"); optional:
    #: a status without it (another client's service) is still a status.
    driver: str | None = None


class TraceEvent(BaseModel):
    """One executed activity node, published on `…/orchestrator/trace` (alone or in a JSON array).

    `seq` numbers the events of one orchestrator run 1, 2, 3 … in recording order; a gap means
    events were dropped. Files recorded before it existed have no `seq`.
    """

    lane: str
    node: str
    kind: str
    start: float  # unix seconds
    end: float  # unix seconds
    duration_ms: float
    value: Any = None
    error: str | None = None
    level: Literal["info", "warning", "error"] = "info"
    detail: str | None = None
    seq: int | None = None


class OrchestratorStatus(BaseModel):
    """Retained state of the orchestrator (`…/orchestrator/status`); its last will says offline."""

    model_config = ConfigDict(extra="allow")

    state: Literal["starting", "running", "stopping", "stopped", "failed", "offline"]
    reason: str | None = None
    model: str | None = None
    #: the run's call time-out in seconds (monitors report an unanswered call after it too).
    call_timeout_s: float | None = None


class Heartbeat(BaseModel):
    """The orchestrator's sign of life (`…/orchestrator/heartbeat`, every `period_s` while it runs).

    `reply_to` is the reply topic of its calls: a motor whose last command came with that reply
    topic keeps running while these arrive (the orchestrator's lease); `seq` counts 0, 1, 2 …
    """

    model_config = ConfigDict(extra="ignore")

    reply_to: str = Field(min_length=1, max_length=512)
    seq: int = Field(ge=0)
    period_s: float = Field(gt=0, allow_inf_nan=False)


class ExitRequest(BaseModel):
    """Ask the orchestrator to finish (`…/orchestrator/exit`); `Application.exit` becomes true."""

    reason: str | None = None


def parse_json(payload: bytes) -> Any:
    """The JSON value of a payload from the wire; `ValueError` for anything that is not UTF-8 JSON.

    Nesting too deep for the decoder (5 000 `[` in a row) and an integer too long to convert are
    `ValueError`s with messages of ours (`umlbot.base.files.loads_json`), never the decoder's
    `RecursionError` or Python's advice to its own programmer: whoever reads the wire answers one
    kind of error, in words for the sender.
    """
    return loads_json(payload.decode("utf-8"))


def json_default(obj: Any) -> Any:
    if isinstance(obj, BaseModel):
        return obj.model_dump(mode="json")
    if isinstance(obj, set | frozenset | tuple):
        return list(obj)
    raise TypeError(f"{type(obj).__name__} is not JSON serialisable")


# one encoder for the hot path: json.dumps with options builds a new encoder on every call
_ENCODER = json.JSONEncoder(separators=(",", ":"), ensure_ascii=False, default=json_default)


def dumps(value: Any) -> str:
    """Compact JSON text (UTF-8 characters kept), as published on the bus."""
    return _ENCODER.encode(value)


def to_payload(payload: Any) -> bytes:
    """Bytes for the wire: bytes as they are, str as UTF-8, a Reply or model as JSON, else JSON."""
    if isinstance(payload, bytes | bytearray | memoryview):
        return bytes(payload)
    if isinstance(payload, str):
        return payload.encode("utf-8")
    if isinstance(payload, Reply):
        return dumps(payload.wire()).encode("utf-8")
    if isinstance(payload, BaseModel):
        return payload.model_dump_json(exclude_none=True).encode("utf-8")
    return dumps(payload).encode("utf-8")
