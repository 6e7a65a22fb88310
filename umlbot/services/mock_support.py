"""What every mock driver shares: settings for latency and faults, and a record of commands.

Mock drivers are package code, like gpiozero's MockFactory, so users can test their own models
without hardware: `umlbot service motor --driver mock`, or `ServiceHost(..., driver="mock")` and
then read `host.drivers["LeftActuator"].commands`. Their settings come from the deployment's
component settings, under keys starting with `mock_` (other keys, such as pins, do nothing here,
so one deployment serves every driver; they are still checked as the hardware drivers check them,
none required: `umlbot.base.registry.hardware_problems`).
"""

from __future__ import annotations

import threading
import time
from collections import deque
from collections.abc import Callable
from typing import Any

from pydantic import BaseModel, ConfigDict, Field, model_validator

from umlbot.base.errors import DriverError

#: calls a mock driver keeps in `commands` unless `mock_record` says otherwise: plenty for a test
#: that looks at a run's calls, about 0.2 MB per driver at most.
DEFAULT_RECORD = 1000


class MockSettings(BaseModel):
    """Settings every mock driver accepts (besides its kind's own `mock_…` keys)."""

    model_config = ConfigDict(extra="ignore", frozen=True)

    mock_latency_s: float = Field(default=0.0, ge=0, le=10, description="delay added to every call")
    mock_faults: dict[str, str] = Field(
        default_factory=dict, description="method name -> message of the DriverError it raises"
    )
    mock_record: int = Field(
        default=DEFAULT_RECORD, ge=1, le=1_000_000,
        description="calls kept in `commands` (the newest; a service that runs for days must not grow)",
    )

    @model_validator(mode="before")
    @classmethod
    def _known_mock_keys(cls, data: Any) -> Any:
        if isinstance(data, dict):
            unknown = sorted(k for k in data if str(k).startswith("mock_") and k not in cls.model_fields)
            if unknown:
                known = sorted(k for k in cls.model_fields if k.startswith("mock_"))
                raise ValueError(f"unknown mock setting(s) {unknown}; known: {known}")
        return data


class MockDriver:
    """Base of the mock drivers: records `(method, args)` in `commands`, injects latency and faults.

    `commands` is a list of the newest `mock_record` calls (default 1000), oldest first: a mock
    service may run for days, so older calls are forgotten; `recorded` counts every call. Drivers
    record a call with `_enter` (with latency and faults) or `_record` (a safety stop, `close`).
    `faults` maps a method name to the message of the `DriverError` it raises (every call, until
    removed); `fail_next(method, message)` makes only the next call fail. `wait_until(predicate)`
    waits (bounded) until the driver's state satisfies a condition, for tests across threads.
    """

    def __init__(self, component: str, settings: MockSettings) -> None:
        self.component = component
        self.latency_s = settings.mock_latency_s
        self.faults: dict[str, str] = dict(settings.mock_faults)
        self._commands: deque[tuple[str, tuple[Any, ...]]] = deque(maxlen=settings.mock_record)
        #: every call recorded, also those no longer in `commands`
        self.recorded = 0
        self.closed = False
        self._one_shot: dict[str, str] = {}
        self._cond = threading.Condition(threading.RLock())

    def fail_next(self, method: str, message: str = "injected fault") -> None:
        """Make the next call of `method` raise `DriverError(message)`."""
        with self._cond:
            self._one_shot[method] = message

    @property
    def commands(self) -> list[tuple[str, tuple[Any, ...]]]:
        """The newest recorded calls as `(method, args)`, oldest first (a copy: safe to keep and
        to iterate while the service runs)."""
        with self._cond:
            return list(self._commands)

    def commands_named(self, method: str) -> list[tuple[Any, ...]]:
        """The argument tuples of the recorded calls of `method` (among the newest kept)."""
        with self._cond:
            return [args for name, args in self._commands if name == method]

    def wait_until(self, predicate: Callable[[], bool], timeout: float = 2.0) -> bool:
        """Wait until `predicate()` holds (checked on every recorded call); True if it did in time."""
        with self._cond:
            return self._cond.wait_for(predicate, timeout)

    def _enter(self, method: str, *args: Any) -> None:
        """Record a call, then apply latency and faults; the caller then changes its state."""
        if self.latency_s:
            time.sleep(self.latency_s)
        with self._cond:
            self._record(method, *args)
            message = self._one_shot.pop(method, None) or self.faults.get(method)
        if message is not None:
            raise DriverError(f"{self.component}: {message}")

    def _record(self, method: str, *args: Any) -> None:
        """Record a call (no latency, no faults) and wake whoever waits in `wait_until`."""
        with self._cond:
            self._commands.append((method, args))
            self.recorded += 1
            self._cond.notify_all()

    def _changed(self) -> None:
        with self._cond:
            self._cond.notify_all()
