"""The `ros2` service kind's driver: one component's view of DDS (this process's participant
in its ROS 2 domain, the message types it uses), and the topics and services it opened.

The driver is the same whatever `driver:` the deployment says (`dds`, and `auto`, `mock`,
`sim`, `pigpio`, `lgpio` too): the hardware is on the other side of DDS, in a ROS 2 driver
node, or in `umlbot sim`'s simulated world playing one.
"""

from __future__ import annotations

import threading
from collections.abc import Callable
from typing import Any, TypeVar

from umlbot.base.errors import ConfigError
from umlbot.base.registry import DriverFactory
from umlbot.services.ros2 import dds
from umlbot.services.ros2.mapping import (
    Ros2Settings,
    ServiceCall,
    SignalMap,
    TopicRead,
    TopicWrite,
    effective_domain,
)
from umlbot.services.ros2.msgtypes import Types

E = TypeVar("E", dds.Subscription, dds.Publication, dds.ServiceClient)


class Ros2Node:
    """What a ROS 2 component opens on DDS; `close()` (idempotent) releases it all."""

    def __init__(self, component: str, settings: Ros2Settings, confirm: bool = False) -> None:
        dds.require()
        self.component = component
        self.settings = settings
        #: in `umlbot sim`: a publish returns once the simulated driver has it, and a read waits
        #: for a reading taken after the call began (the sim's time stands still during a call)
        self.confirm = confirm
        try:
            self.domain_id = effective_domain(settings.domain_id)
        except ValueError as exc:
            raise ConfigError(f"{component}: {exc}") from None
        self.types = Types.load(tuple(settings.msg_paths))
        self.builder = dds.TypeBuilder.of(self.types)
        dds.participant(self.domain_id)
        self._opened: list[dds.Subscription | dds.Publication | dds.ServiceClient] = []
        self._lock = threading.Lock()
        self.closed = False

    def _keep(self, entity: E) -> E:
        with self._lock:
            self._opened.append(entity)
        return entity

    def subscribe(self, read: TopicRead) -> dds.Subscription:
        return self._keep(dds.Subscription(self.builder, self.domain_id, read.topic, read.type,
                                           reliable=read.reliable))

    def subscribe_signal(self, signal: SignalMap, on_sample: Callable[[Any], None]) -> dds.Subscription:
        return self._keep(dds.Subscription(self.builder, self.domain_id, signal.topic, signal.type,
                                           reliable=signal.reliable, on_sample=on_sample))

    def publisher(self, write: TopicWrite) -> dds.Publication:
        return self._keep(dds.Publication(self.builder, self.domain_id, write.topic, write.type))

    def client(self, call: ServiceCall) -> dds.ServiceClient:
        return self._keep(dds.ServiceClient(self.builder, self.domain_id, call.service, call.type))

    def close(self) -> None:
        with self._lock:
            if self.closed:
                return
            self.closed = True
            opened, self._opened = self._opened, []
        for entity in opened:
            entity.close()


def create(component: str, settings: Ros2Settings) -> Ros2Node:
    return Ros2Node(component, settings)


def create_confirming(component: str, settings: Ros2Settings) -> Ros2Node:
    return Ros2Node(component, settings, confirm=True)


FACTORY = DriverFactory(Ros2Settings, create)
#: `driver: sim`: the world of `umlbot sim` plays the ROS 2 drivers (umlbot.sim.ros2_world)
SIM_FACTORY = DriverFactory(Ros2Settings, create_confirming)
