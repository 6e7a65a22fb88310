"""CDR of the two messages a run records most (a `TraceEvent` per node, a `FeatureCall` per call),
made straight from the wire's values in one `struct` pass.

rosbags' path makes the message object first (`Builder.trace`, `Builder.call`), then walks it with
its generated serialiser: about 17 µs a trace event here, against about 4 µs for this one
(docs/performance.md, Recording). The bytes are the same as rosbags' for every value (the tests
compare them): XCDR1 little endian, strings as a uint32 length with their NUL, each field aligned
to its size from the end of the 4-byte encapsulation header. The values are cleaned as `Builder`
cleans them (a wrong type recorded as empty, a non-finite number as 0).
"""

from __future__ import annotations

import struct
from functools import lru_cache
from typing import Any

from umlbot.record.messages import _number, _text, json_text, to_ns

#: the encapsulation header of little-endian plain CDR
HEADER = b"\x00\x01\x00\x00"
_MAX_SEC = 2**31 - 1


def _string(parts: list[str], offset: int, size: int) -> int:
    """Append a string of `size` bytes at `offset` to the format `parts`; the offset after it."""
    pad = -offset & 3
    if pad:
        parts.append(f"{pad}x")
        offset += pad
    parts.append(f"I{size + 1}s")  # `s` pads the bytes with the string's NUL
    return offset + 4 + size + 1


@lru_cache(maxsize=4096)
def _trace_format(lane: int, node: int, kind: int, value: int, level: int, error: int,
                  detail: int) -> Any:
    parts, offset = ["<4siIQ"], 16  # header; stamp sec, nanosec; seq
    for size in (lane, node, kind):
        offset = _string(parts, offset, size)
    pad = -offset & 7
    if pad:
        parts.append(f"{pad}x")
    parts.append("ddd")  # start, end, duration_ms
    offset += pad + 24
    for size in (value, level, error, detail):
        offset = _string(parts, offset, size)
    return struct.Struct("".join(parts)).pack


@lru_cache(maxsize=4096)
def _call_format(component: int, feature: int, call_id: int, args: int, value: int, code: int,
                 message: int) -> Any:
    parts, offset = ["<4siI"], 8  # header; stamp sec, nanosec
    for size in (component, feature, call_id, args):
        offset = _string(parts, offset, size)
    parts.append("??")  # answered, ok
    offset += 2
    for size in (value, code, message):
        offset = _string(parts, offset, size)
    pad = -offset & 7
    if pad:
        parts.append(f"{pad}x")
    parts.append("d")  # latency_ms
    return struct.Struct("".join(parts)).pack


def _float(value: Any) -> float:
    # a finite float as it is (x - x is nan for inf and nan); anything else as Builder cleans it
    return value if type(value) is float and value - value == 0.0 else _number(value)


def _str(value: Any) -> bytes:
    return (value if type(value) is str else _text(value)).encode()


def trace_event(event: dict[str, Any]) -> tuple[bytes, int]:
    """The CDR of `Builder.trace(event)` and its stamp (ns: the event's end)."""
    get = event.get
    end = _float(get("end"))
    ns = to_ns(end)
    seq = get("seq")
    value = get("value")
    lane, node, kind = _str(get("lane")), _str(get("node")), _str(get("kind"))
    value_json = b"" if value is None else json_text(value).encode()
    level = _str(get("level")) or b"info"
    error, detail = _str(get("error")), _str(get("detail"))
    pack = _trace_format(len(lane), len(node), len(kind), len(value_json), len(level), len(error),
                         len(detail))
    data = pack(HEADER, min(ns // 1_000_000_000, _MAX_SEC), ns % 1_000_000_000,
                seq if isinstance(seq, int) and 0 <= seq < 2**64 else 0,
                len(lane) + 1, lane, len(node) + 1, node, len(kind) + 1, kind,
                _float(get("start")), end, _float(get("duration_ms")),
                len(value_json) + 1, value_json, len(level) + 1, level, len(error) + 1, error,
                len(detail) + 1, detail)
    return data, ns


def feature_call(at: float, component: str, feature: str, call_id: str | None,
                 args: list[Any] | None, ok: bool | None, value: Any, error: str | None,
                 latency_ms: float | None) -> tuple[bytes, int]:
    """The CDR of `Builder.call(...)` (same arguments) and its stamp (ns: `at`)."""
    code, _, message = (error or "").partition(": ")
    answered = latency_ms is not None
    ns = to_ns(at)
    fields = [text.encode() for text in (
        component, feature, call_id or "", json_text(args if args is not None else []),
        json_text(value) if ok else "", code if error else "", message if message else (error or ""))]
    pack = _call_format(*(len(field) for field in fields))
    c_, f_, i_, a_, v_, e_, m_ = fields
    return pack(HEADER, min(ns // 1_000_000_000, _MAX_SEC), ns % 1_000_000_000,
                len(c_) + 1, c_, len(f_) + 1, f_, len(i_) + 1, i_, len(a_) + 1, a_,
                answered, bool(ok) and answered,
                len(v_) + 1, v_, len(e_) + 1, e_, len(m_) + 1, m_,
                float(latency_ms) if latency_ms is not None else -1.0), ns
