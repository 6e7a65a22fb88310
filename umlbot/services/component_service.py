"""What the service host needs from one served component: its features, state and safe stop.

A `ComponentService` sits between the bus and one driver: it turns the implementation's features
(from `umlbot.base.library`) into bus `Feature`s whose handlers call the driver, keeps the component's
state (published retained on `…/<component>/state` after every change) and knows how to put the
hardware into a safe state. Driver errors become error replies: `ValueError` (an argument the
hardware refuses) → `out_of_range`, `DriverError` → `driver_error`.
"""

from __future__ import annotations

import threading
from collections.abc import Callable, Mapping
from typing import Any, ClassVar

from umlbot.base.errors import ConfigError, DriverError
from umlbot.base.library import Implementation, ServiceKind
from umlbot.base.logs import get_logger
from umlbot.services.bus import Feature, FeatureError

log = get_logger("umlbot.service")

StatePublisher = Callable[[dict[str, Any]], None]


class ComponentService:
    """Base of the per-kind services (`umlbot/services/<kind>/service.py`).

    Subclasses set `kind` and `handlers` (feature name -> method name) and implement `state()`.
    `settings` is the component's raw deployment settings (service-level keys such as
    `watchdog_s` are read from there; the driver validated its own).
    """

    kind: ClassVar[ServiceKind]
    handlers: ClassVar[dict[str, str]] = {}

    def __init__(self, component: str, impl: Implementation, driver: Any,
                 settings: Mapping[str, Any] | None = None) -> None:
        self.component = component
        self.impl = impl
        self.driver = driver
        self.settings = dict(settings or {})
        self.lock = threading.RLock()
        self.publish_state: StatePublisher = lambda state: None
        self.log = log.bind(component=component, kind=self.kind)
        self._closed = False
        missing = sorted(set(impl.features) - set(self.handlers))
        if missing:
            raise ConfigError(f"{component}: the {self.kind} service cannot serve feature(s) {missing}")

    def features(self) -> list[Feature]:
        """The bus features of this component: the implementation's, with this service's handlers."""
        return [
            Feature(spec, self._guarded(getattr(self, self.handlers[name])))
            for name, spec in sorted(self.impl.features.items())
        ]

    def _guarded(self, handler: Callable[..., Any]) -> Callable[..., Any]:
        def call(*args: Any) -> Any:
            try:
                return handler(*args)
            except FeatureError:
                raise
            except DriverError:
                raise
            except ValueError as exc:
                raise FeatureError("out_of_range", str(exc)) from exc

        return call

    def state(self) -> dict[str, Any]:
        """The component's current state, as published (JSON-able)."""
        raise NotImplementedError

    def changed(self) -> None:
        """Publish the state (call after every change)."""
        self.publish_state(self.state())

    def safe_stop(self, reason: str) -> None:
        """Put the hardware in a safe state (motors: stopped). Default: nothing to do."""

    def on_server(self, server: Any) -> None:
        """The component's bus server (a `ComponentServer`), before it connects: for a service
        that subscribes or publishes beyond its features (ROS 2 signals). Default: nothing."""

    def tick(self, now: float) -> None:
        """Called periodically by the host with `time.monotonic()` (motors: the watchdog)."""

    def orchestrator_heartbeat(self, reply_to: str) -> None:
        """The orchestrator whose calls come with this reply topic is alive (its heartbeat; only
        for the kinds that stop when it goes offline). Default: nothing to do."""

    def close(self) -> None:
        """Safe stop, then release the driver; idempotent and never raises."""
        with self.lock:
            if self._closed:
                return
            self._closed = True
        try:
            self.safe_stop("service stopping")
        except Exception:
            self.log.exception("safe stop failed")
        try:
            self.driver.close()
        except Exception:
            self.log.exception("driver close failed")
