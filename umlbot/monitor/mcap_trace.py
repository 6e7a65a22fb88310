"""Reading the trace of an MCAP recording (`umlbot sim/run --record`, `umlbot record`) for replay.

The file is read as a stream (no index needed: a recording cut short by a full disk ends with a
footer and reads to its end), every channel whose schema is `umlbot_msgs/msg/TraceEvent` is
decoded with the message definition the file carries (`mcap-ros2-support`), and each message
becomes the `TraceEvent` a JSON-lines trace holds. A file that breaks off (killed while writing,
copied in part) or is damaged raises ConfigError saying at which byte and after how many trace
events: never a traceback.
"""

from __future__ import annotations

import json
from collections.abc import Iterator
from pathlib import Path
from typing import Any, Final

from pydantic import ValidationError

from umlbot.base.errors import ConfigError
from umlbot.base.rosmsg import require
from umlbot.services.bus import TraceEvent

MAGIC: Final = b"\x89MCAP0\r\n"
TRACE_TYPE: Final = "umlbot_msgs/msg/TraceEvent"


def is_mcap(path: Path) -> bool:
    """Whether the file starts like an MCAP file (a missing file is left to the caller's error)."""
    try:
        with path.open("rb") as handle:
            return handle.read(len(MAGIC)) == MAGIC
    except OSError:
        return False


def read_mcap_trace(path: Path) -> Iterator[TraceEvent]:
    """The trace events of an MCAP recording in the order they were written."""
    stream_reader = require("mcap.stream_reader", "record", "Replaying MCAP recordings")
    records = require("mcap.records", "record", "Replaying MCAP recordings")
    decoders = require("mcap_ros2.decoder", "record", "Replaying MCAP recordings")
    factory = decoders.DecoderFactory()
    try:
        handle = path.open("rb")
        size = path.stat().st_size
    except OSError as exc:
        raise ConfigError(f"cannot read recording {path}: {exc.strerror or exc}") from exc
    schemas: dict[int, Any] = {}
    trace_channels: dict[int, Any] = {}  # channel id -> decoder
    events = 0
    done = 0  # bytes read whole
    footer = False
    with handle:
        reader = stream_reader.StreamReader(handle, skip_magic=False, validate_crcs=True)
        try:
            for record in reader.records:
                done = handle.tell()
                if isinstance(record, records.Schema):
                    schemas[record.id] = record
                elif isinstance(record, records.Channel):
                    schema = schemas.get(record.schema_id)
                    if schema is not None and schema.name == TRACE_TYPE:
                        decoder = factory.decoder_for(record.message_encoding, schema)
                        if decoder is None:
                            raise ConfigError(f"{path}: the trace channel {record.topic} is encoded as "
                                              f"{record.message_encoding!r}, not CDR")
                        trace_channels[record.id] = decoder
                elif isinstance(record, records.Message):
                    decoder = trace_channels.get(record.channel_id)
                    if decoder is not None:
                        yield _event(decoder(record.data), path, events + 1)
                        events += 1
                elif isinstance(record, records.Footer):
                    footer = True
        except ConfigError:
            raise
        except Exception as exc:  # the mcap package's errors, struct errors, bad CDR
            what = type(exc).__name__ if not str(exc) else f"{type(exc).__name__}: {exc}"
            raise ConfigError(
                f"{path}: the MCAP file breaks off or is damaged after byte {done} of {size} ({what}); "
                f"{events} trace events were read before it") from None
    if not footer:
        raise ConfigError(f"{path}: the MCAP file breaks off after byte {done} of {size} (no footer: the "
                          f"recording was cut short); {events} trace events were read before it")


def _event(message: Any, path: Path, number: int) -> TraceEvent:
    """The `TraceEvent` of one decoded `umlbot_msgs/msg/TraceEvent`."""
    try:
        value = json.loads(message.value_json) if message.value_json else None
        return TraceEvent(
            lane=message.lane, node=message.node, kind=message.kind, start=message.start, end=message.end,
            duration_ms=message.duration_ms, value=value, error=message.error or None,
            level=message.level or "info", detail=message.detail or None, seq=message.seq or None,
        )
    except (AttributeError, ValueError, ValidationError) as exc:
        raise ConfigError(f"{path}: trace event {number} is not an umlbot trace event: {exc}") from None
