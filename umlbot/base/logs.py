"""Logging, configured once: human-readable on a terminal, JSON lines otherwise."""

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


def configure_logging(level: str | None = None, json: bool | None = None) -> None:
    """Configure structlog and the stdlib root logger; later calls only change the level.

    `level` defaults to `UMLBOT_LOG_LEVEL` or INFO; `json` defaults to "stderr is not a terminal".
    """
    global _configured
    level_name = (level or os.environ.get("UMLBOT_LOG_LEVEL") or "INFO").upper()
    numeric = logging.getLevelNamesMapping().get(level_name, logging.INFO)
    if _configured:
        logging.getLogger().setLevel(numeric)
        return
    _configured = True
    if json is None:
        json = not sys.stderr.isatty()
    shared: list[Any] = [
        structlog.contextvars.merge_contextvars,
        structlog.stdlib.add_log_level,
        structlog.stdlib.add_logger_name,
        structlog.processors.TimeStamper(fmt="iso", utc=True),
    ]
    renderer: Any = (
        structlog.processors.JSONRenderer() if json else structlog.dev.ConsoleRenderer(colors=True)
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
