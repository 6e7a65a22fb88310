"""Logging, configured once: human-readable on a terminal, JSON lines otherwise."""

from __future__ import annotations

import importlib
import logging
import os
import sys
import types
from typing import Any


class _Deferred(types.ModuleType):
    """Stands in for a module while structlog is imported; the real one is imported on first use.

    structlog imports asyncio at the top of `structlog.stdlib` but uses it only inside its `a…`
    coroutine methods (`await log.ainfo(...)`), which the services never call: importing it anyway
    costs about 2 MB in every process. Attributes are looked up on the real module, imported then
    (by the import system, with its locks), so the asyncio programs (broker, studio) are unchanged.
    """

    def __getattr__(self, name: str) -> Any:
        if sys.modules.get(self.__name__) is self:
            raise AttributeError(f"{self.__name__}.{name} used while structlog is being imported")
        return getattr(importlib.import_module(self.__name__), name)


def _import_structlog() -> None:
    """Import structlog without what it only imports, for features umlbot does not use.

    - rich (about 4 MB), when installed, only draws tracebacks on a terminal; its plain tracebacks
      say the same, and `umlbot monitor` imports rich itself.
    - greenlet (about 1 MB; installed with the test tools) only backs the deprecated
      `structlog.threadlocal`, which then uses `threading.local`.
    - asyncio: see `_Deferred`.

    A module imported before this (e.g. rich by the monitor) is used as it is. The stand-ins are
    taken out of `sys.modules` again afterwards, so later imports get the real modules.
    """
    stand_ins: dict[str, types.ModuleType | None] = {}
    for name in ("rich", "greenlet"):
        if name not in sys.modules:
            stand_ins[name] = None  # makes `import rich` raise ImportError
    if "asyncio" not in sys.modules:
        stand_ins["asyncio"] = _Deferred("asyncio")
    sys.modules.update(stand_ins)  # type: ignore[arg-type]  # None blocks an import
    try:
        import structlog  # noqa: F401  # bound globally below
    finally:
        for name, stand_in in stand_ins.items():
            if sys.modules.get(name) is stand_in:
                del sys.modules[name]


_import_structlog()
import structlog  # noqa: E402  # already imported by _import_structlog

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
