"""Helpers for the hardware service tests (tests/test_services_*.py): deployments, a running
ServiceHost, a BusClient and reading retained state, all against the real broker fixtures."""

from __future__ import annotations

import json
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from typing import Any

from umlbot.base.deployment import Deployment
from umlbot.base.library import ServiceKind
from umlbot.services.bus import BrokerSettings, BusClient, Topics
from umlbot.services.host import ServiceHost
from umlbot.services.simworld import attach_local_world
from umlbot.sim import World, parse_track

ROBOT = "car"

#: The reference robot with every setting a driver needs (pins from SPEC §1).
REFERENCE: dict[str, Any] = {
    "robot": ROBOT,
    "driver": "mock",
    "components": {
        "RaspberryPI": {"impl": "CModelSystemRaspberryPI", "settings": {"pins": [4, 17, 27]}},
        "LeftActuator": {"impl": "CModelL298NActuator", "settings": {"in1": 22, "in2": 23}},
        "RightActuator": {"impl": "l298n", "settings": {"in1": 24, "in2": 25}},
        "Sensor": {"impl": "CModelActuator", "settings": {"gpio": 18}},
        "DistanceRead": {"impl": "CModelDistanceSensorHCSR", "settings": {"trigger": 8, "echo": 7}},
    },
}


def deployment(driver: str = "mock", **settings: dict[str, Any]) -> Deployment:
    """The reference deployment; keyword arguments add settings per component."""
    data = json.loads(json.dumps(REFERENCE))
    data["driver"] = driver
    for component, extra in settings.items():
        data["components"][component]["settings"].update(extra)
    return Deployment.model_validate(data)


#: A 2 m x 3 m room with the car in the middle facing +y: side walls 1 m away, front wall 2 m.
ROOM = """
name: room
start: {x: 0.0, y: 0.0, heading_deg: 90}
goal: {x_min: -0.2, x_max: 0.2, y_min: 1.5, y_max: 1.9}
walls:
  - [[-1.0, -1.0], [1.0, -1.0], [1.0, 2.0], [-1.0, 2.0], [-1.0, -1.0]]
"""


@contextmanager
def sim_world(track: str = ROOM) -> Iterator[World]:
    """A simulated world attached to this process, so services on the sim driver act on it."""
    world = World(parse_track(track))
    attach_local_world(world)
    try:
        yield world
    finally:
        attach_local_world(None)


def broker_settings(url: str) -> BrokerSettings:
    return BrokerSettings.from_url(url)


@contextmanager
def running(kind: ServiceKind, dep: Deployment, url: str, driver: str | None = None) -> Iterator[ServiceHost]:
    """A started ServiceHost, stopped afterwards whatever happens."""
    host = ServiceHost(kind, dep, broker_settings(url), ROBOT, driver)
    with host:
        yield host


@contextmanager
def client(url: str) -> Iterator[BusClient]:
    with BusClient(broker_settings(url), ROBOT, role="test") as bus:
        yield bus


class StateWatch:
    """Collects the retained `state` messages of components through a BusClient subscription."""

    def __init__(self, bus: BusClient, *components: str) -> None:
        self.topics = Topics(ROBOT)
        self.latest: dict[str, dict[str, Any]] = {}
        self.history: list[tuple[str, dict[str, Any]]] = []
        for component in components:
            bus.subscribe(self.topics.state(component), self._on_state)

    def _on_state(self, message: Any) -> None:
        component = message.topic.split("/")[-2]
        state = json.loads(message.payload)
        self.latest[component] = state
        self.history.append((component, state))

    def wait(
        self, component: str, predicate: Callable[[dict[str, Any]], bool], timeout: float = 5.0
    ) -> dict[str, Any]:
        """The component's latest state once `predicate` holds; AssertionError after `timeout`."""
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            state = self.latest.get(component)
            if state is not None and predicate(state):
                return state
            time.sleep(0.01)
        raise AssertionError(f"state of {component} never matched; last: {self.latest.get(component)}")


def wait_for(predicate: Callable[[], bool], timeout: float = 5.0) -> bool:
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if predicate():
            return True
        time.sleep(0.01)
    return predicate()


def raw_state(raw: Any, component: str, predicate: Callable[[dict[str, Any]], bool],
              timeout: float = 5.0) -> dict[str, Any]:
    """Read a raw client's messages on the component's state topic until `predicate` holds."""
    topic = Topics(ROBOT).state(component)
    deadline = time.monotonic() + timeout
    last: dict[str, Any] | None = None
    while time.monotonic() < deadline:
        try:
            last = json.loads(raw.get(timeout=max(0.01, deadline - time.monotonic()), topic=topic).payload)
        except TimeoutError:
            break
        if last is not None and predicate(last):
            return last
    raise AssertionError(f"state of {component} never matched; last: {last}")
