"""The simulated world playing a robot's ROS 2 drivers over real DDS (`umlbot sim` of a model
whose components are ROS 2 mappings, e.g. models/ros2_car):

- for each `ros2_twist` component, a base driver: it subscribes the component's topic
  (`/cmd_vel`) and turns each `geometry_msgs/msg/Twist` into the two sides' motor commands
  (side speed = linear.x ∓ angular.z x track / 2; duty = |speed| / top speed x 100, at most 100);
- for each `ros2_range` component, a range driver: it publishes `sensor_msgs/msg/Range` on the
  component's topic (`/range`) every `RANGE_PERIOD_WALL_S` wall seconds, the sonar's reading at
  that moment (no echo: +inf, REP 117), taking no robot time.

The components' service runs on its `sim` driver, which waits for the base driver's
acknowledgement of each Twist and, for a read, for a Range published after the call began
(sim time stands still while a call is in flight): the run is the same at any `--speed`.
"""

from __future__ import annotations

import math
import threading
from typing import Any

from umlbot.base.logs import get_logger
from umlbot.services.simworld import Side
from umlbot.sim.world import World

log = get_logger("umlbot.sim.ros2")

RANGE_PERIOD_WALL_S = 0.005


class Ros2WorldDrivers:
    """The ROS 2 drivers the world plays for one deployment; `start()`, `stop()` (idempotent)."""

    def __init__(self, world: World, deployment: Any) -> None:
        self.world = world
        self.deployment = deployment
        self._opened: list[Any] = []
        self._threads: list[threading.Thread] = []
        self._stop = threading.Event()
        #: Twists applied and Ranges published, for the run's figures
        self.twists = 0
        self.ranges = 0

    @staticmethod
    def needed(deployment: Any) -> bool:
        return any(comp.impl in ("ros2_twist", "ros2_range") for comp in deployment.components.values())

    def start(self) -> None:
        from umlbot.services.ros2 import dds
        from umlbot.services.ros2.mapping import Ros2Settings, effective_domain
        from umlbot.services.ros2.msgtypes import Types

        for name, comp in sorted(self.deployment.components.items()):
            if comp.impl not in ("ros2_twist", "ros2_range"):
                continue
            settings = Ros2Settings.model_validate(
                {k: v for k, v in comp.settings.items() if not k.startswith(("mock_", "sim_"))})
            domain = effective_domain(settings.domain_id)
            builder = dds.TypeBuilder.of(Types.load(tuple(settings.msg_paths)))
            if comp.impl == "ros2_twist":
                topic = settings.topic or "/cmd_vel"
                self._opened.append(dds.Subscription(builder, domain, topic, "geometry_msgs/msg/Twist",
                                                     reliable=True, on_sample=self._twist))
                log.info("sim_ros2_base", component=name, topic=topic, domain_id=domain)
            else:
                topic = settings.topic or "/range"
                pub = dds.Publication(builder, domain, topic, "sensor_msgs/msg/Range")
                self._opened.append(pub)
                thread = threading.Thread(target=self._ranges, args=(pub, name), daemon=True,
                                          name=f"sim-ros2-range-{name}")
                self._threads.append(thread)
                log.info("sim_ros2_range", component=name, topic=topic, domain_id=domain)
        for thread in self._threads:
            thread.start()

    def _twist(self, twist: Any) -> None:
        car = self.world.car
        half = twist.angular.z * car.turn_track_m / 2
        sides: tuple[tuple[Side, float], ...] = (("left", twist.linear.x - half),
                                                 ("right", twist.linear.x + half))
        for side, speed in sides:
            duty = min(100.0, abs(speed) / car.top_speed_mps * 100.0)
            self.world.set_motor(side, enabled=duty > 0, forward=speed >= 0, duty_percent=duty)
        self.twists += 1

    def _ranges(self, pub: Any, frame: str) -> None:
        car = self.world.car
        while not self._stop.wait(RANGE_PERIOD_WALL_S):  # a halted world still answers
            cm = self.world.read_sonar_cm(charge=False)
            sample = pub.sample()
            sample.header.frame_id = frame
            now = self.world.time_s()
            sample.header.stamp.sec, sample.header.stamp.nanosec = int(now), int((now % 1) * 1e9)
            sample.radiation_type = 0  # ULTRASOUND
            sample.field_of_view = math.radians(car.sonar_beam_deg)
            sample.min_range, sample.max_range = car.sonar_min_cm / 100, car.sonar_max_cm / 100
            sample.range = math.inf if cm is None else cm / 100
            try:
                pub.write(sample)
            except Exception:  # DDS shutting down
                log.debug("sim_ros2_range_write_failed", frame=frame)
                return
            self.ranges += 1

    def stop(self) -> None:
        self._stop.set()
        for thread in self._threads:
            thread.join(timeout=2.0)
        for entity in self._opened:
            entity.close()
        self._opened.clear()
