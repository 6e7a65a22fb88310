"""Helpers for the orchestrator tests: compile a test model, serve it with mock drivers, run it.

`Rig(broker, model_path)` compiles the model (tests/models/…), starts one in-process `ServiceHost`
per service kind the model uses (driver `mock`, so `rig.driver("LeftActuator").commands` is what
the hardware would have seen), and runs an `Orchestrator` in a background thread with a trace
listener that collects every `TraceEvent` dict.
"""

from __future__ import annotations

import asyncio
import contextlib
import threading
import time
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from umlbot.base.deployment import ComponentDeployment, Deployment
from umlbot.base.library import ServiceKind
from umlbot.compiler.api import compile_model
from umlbot.compiler.compiled import CompiledModel
from umlbot.services.bus import BrokerSettings
from umlbot.services.host import ServiceHost
from umlbot.services.orchestrator import Orchestrator

MODELS = Path(__file__).parent / "models"
ROBOT_CAR = Path(__file__).parent.parent / "models" / "robot_car"


def deployment_of(model: CompiledModel, driver: str = "mock",
                  settings: dict[str, dict[str, Any]] | None = None) -> Deployment:
    """The deployment the compiled model carries, with every driver set to `driver`."""
    extra = settings or {}
    return Deployment(
        driver=driver,
        components={
            name: ComponentDeployment(impl=comp.impl, driver=driver,
                                      settings={**comp.settings, **extra.get(name, {})})
            for name, comp in model.components.items()
        },
    )


@dataclass
class Running:
    """An orchestrator running in a background thread."""

    orchestrator: Orchestrator
    thread: threading.Thread
    result: dict[str, Any] = field(default_factory=dict)

    def wait(self, timeout: float = 10.0) -> int:
        """The exit code; on time-out the run is asked to exit and an AssertionError raised."""
        self.thread.join(timeout)
        if self.thread.is_alive():
            self.orchestrator.request_exit("test time-out")
            self.orchestrator.request_exit("test time-out")
            self.thread.join(10.0)
            raise AssertionError(f"the orchestrator did not finish within {timeout} s")
        if "error" in self.result:
            raise self.result["error"]
        code: int = self.result["code"]
        return code


class Rig:
    """A compiled test model, its mock services on a real broker, and a trace collector."""

    def __init__(self, broker_url: str, model: str | Path | CompiledModel, robot: str = "test",
                 services: list[ServiceKind] | None = None,
                 settings: dict[str, dict[str, Any]] | None = None) -> None:
        if isinstance(model, CompiledModel):
            self.model = model
        else:
            path = Path(model)
            self.model = compile_model(path if path.exists() else MODELS / path)
        self.broker_url = broker_url
        self.settings = BrokerSettings.from_url(broker_url)
        self.robot = robot
        self.deployment = deployment_of(self.model, settings=settings)
        kinds = services if services is not None else sorted(
            {comp.service for comp in self.model.components.values()}
        )
        self.hosts: dict[str, ServiceHost] = {}
        self.events: list[dict[str, Any]] = []
        self._events_lock = threading.Lock()
        for kind in kinds:
            host = ServiceHost(kind, self.deployment, self.settings, robot, driver="mock")
            self.hosts[kind] = host
        for host in self.hosts.values():
            host.start()

    def driver(self, component: str) -> Any:
        """The mock driver of a component."""
        for host in self.hosts.values():
            if component in host.drivers:
                return host.drivers[component]
        raise KeyError(component)

    def host_of(self, component: str) -> ServiceHost:
        for host in self.hosts.values():
            if component in host.drivers:
                return host
        raise KeyError(component)

    def _listen(self, event: dict[str, Any]) -> None:
        with self._events_lock:
            self.events.append(event)

    def trace(self, kind: str | None = None, lane: str | None = None) -> list[dict[str, Any]]:
        """The collected trace events (optionally of one node kind / lane), in arrival order."""
        with self._events_lock:
            return [e for e in self.events
                    if (kind is None or e["kind"] == kind) and (lane is None or e["lane"] == lane)]

    def nodes(self, lane: str | None = None) -> list[str]:
        """The node ids executed, in order."""
        return [e["node"] for e in self.trace(lane=lane)]

    def orchestrator(self, **options: Any) -> Orchestrator:
        options.setdefault("handle_signals", False)
        options.setdefault("startup_timeout_s", 5.0)
        options.setdefault("trace_listener", self._listen)
        return Orchestrator(self.model, self.settings, robot=self.robot, **options)

    def start(self, **options: Any) -> Running:
        """Run an orchestrator in a background thread."""
        orchestrator = self.orchestrator(**options)
        running = Running(orchestrator, threading.Thread(target=lambda: None))

        def target() -> None:
            try:
                running.result["code"] = asyncio.run(orchestrator.run())
            except BaseException as exc:
                running.result["error"] = exc

        running.thread = threading.Thread(target=target, name="orchestrator", daemon=True)
        running.thread.start()
        return running

    def run(self, timeout: float = 10.0, **options: Any) -> tuple[int, Orchestrator]:
        """Run an orchestrator to its end (bounded); returns (exit code, orchestrator)."""
        running = self.start(**options)
        return running.wait(timeout), running.orchestrator

    def close(self) -> None:
        for host in self.hosts.values():
            with contextlib.suppress(Exception):
                host.stop()


@contextlib.contextmanager
def rig(broker_url: str, model: str | Path | CompiledModel, **kwargs: Any) -> Iterator[Rig]:
    """A `Rig` that is closed afterwards."""
    made = Rig(broker_url, model, **kwargs)
    try:
        yield made
    finally:
        made.close()


def wait_for(predicate: Callable[[], bool], timeout: float = 5.0, interval: float = 0.01) -> bool:
    """Poll `predicate` until it holds or `timeout` passes."""
    deadline = time.monotonic() + timeout
    while not predicate():
        if time.monotonic() > deadline:
            return False
        time.sleep(interval)
    return True
