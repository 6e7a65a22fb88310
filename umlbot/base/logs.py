"""Logging, configured once: human-readable on a terminal, JSON lines otherwise (plain sentences for
a command a person runs, unless JSON is asked for)."""

from __future__ import annotations

import logging
import os
import sys
from typing import Any

from umlbot.base.lazy import import_lean

# structlog without what it imports only for features umlbot does not use:
# - rich (about 4 MB), when installed, only draws tracebacks on a terminal; its plain tracebacks
#   say the same, and `umlbot monitor` imports rich itself;
# - greenlet (about 1 MB; installed with the test tools) only backs the deprecated
#   `structlog.threadlocal`, which then uses `threading.local`;
# - asyncio (about 2 MB), imported at the top of `structlog.stdlib`, is used only inside its `a…`
#   coroutine methods (`await log.ainfo(...)`), which the services never call: deferred, so the
#   asyncio programs (broker, studio, orchestrator) are unchanged.
import_lean("structlog.stdlib", deferred=("asyncio",), blocked=("rich", "greenlet"))
import structlog  # noqa: E402  # already imported, lean

_configured = False


def plain_sentence(logger: Any, method: str, event: dict[str, Any]) -> str:
    """A log event as a person reads it on a stderr that is not a terminal (under `make`, in an
    editor's console): `warning: default broker port taken, using a free one (port 1883, …)` —
    no timestamp, no logger name, no colour codes."""
    level = str(event.pop("level", method))
    message = str(event.pop("event", ""))
    for key in ("timestamp", "logger", "logger_name"):
        event.pop(key, None)
    rest = event.pop("exception", None)
    details = ", ".join(f"{key} {value}" for key, value in event.items())
    line = f"{level}: {message}" + (f" ({details})" if details else "")
    return f"{line}\n{rest}" if rest else line


def configure_logging(level: str | None = None, json: bool | None = None, person: bool = False) -> None:
    """Configure structlog and the stdlib root logger; later calls only change the level.

    `level` defaults to `UMLBOT_LOG_LEVEL` or INFO; `json` defaults to "stderr is not a terminal",
    except for a command a person runs (`person`: `umlbot sim`, `umlbot studio`, …), whose logs
    are JSON only when asked for (`--log-json`, `UMLBOT_LOG_JSON=1`): on a stderr that is not a
    terminal they are plain sentences (`plain_sentence`).
    """
    global _configured
    level_name = (level or os.environ.get("UMLBOT_LOG_LEVEL") or "INFO").upper()
    numeric = logging.getLevelNamesMapping().get(level_name, logging.INFO)
    if _configured:
        logging.getLogger().setLevel(numeric)
        return
    _configured = True
    terminal = sys.stderr.isatty()
    if json is None and os.environ.get("UMLBOT_LOG_JSON", "").strip().lower() in ("1", "true", "yes"):
        json = True
    if json is None:
        json = not terminal and not person
    shared: list[Any] = [
        structlog.contextvars.merge_contextvars,
        structlog.stdlib.add_log_level,
        structlog.stdlib.add_logger_name,
        structlog.processors.TimeStamper(fmt="iso", utc=True),
    ]
    renderer: Any = (
        structlog.processors.JSONRenderer() if json
        else structlog.dev.ConsoleRenderer(colors=True) if terminal else plain_sentence
    )
    structlog.configure(
        processors=[*shared, structlog.stdlib.ProcessorFormatter.wrap_for_formatter],
        logger_factory=structlog.stdlib.LoggerFactory(),
        wrapper_class=structlog.stdlib.BoundLogger,
        cache_logger_on_first_use=True,
    )
    handler = logging.StreamHandler(sys.stderr)
    handler.setFormatter(
        structlog.stdlib.ProcessorFormatter(
            foreign_pre_chain=shared,
            processors=[
                structlog.stdlib.ProcessorFormatter.remove_processors_meta,
                structlog.processors.format_exc_info,
                renderer,
            ],
        )
    )
    root = logging.getLogger()
    root.handlers[:] = [handler]
    root.setLevel(numeric)
    # amqtt and paho are chatty at INFO; their warnings still show.
    for noisy in ("amqtt", "transitions", "paho"):
        logging.getLogger(noisy).setLevel(max(numeric, logging.WARNING))


def get_logger(name: str) -> structlog.stdlib.BoundLogger:
    """A named structlog logger; works before and after `configure_logging`."""
    return structlog.stdlib.get_logger(name)
