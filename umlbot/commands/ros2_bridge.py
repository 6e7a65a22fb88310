"""`umlbot ros2-bridge`: the robot seen from ROS 2 (umlbot.services.ros2.bridge): its status,
states (the sonar as sensor_msgs/msg/Range) and trace published on DDS with ROS 2's naming, and
its features callable as the ROS 2 service /umlbot/<robot>/call. Loopback only unless
CYCLONEDDS_URI says otherwise (docs/ros2.md)."""

from __future__ import annotations

import os
from pathlib import Path

import click

from umlbot.base.stopsignals import StopSignals
from umlbot.commands.options import seconds


@click.command(name="ros2-bridge")
@click.option("--broker", "broker_url", default=None, metavar="URL",
              help="Broker URL (default: $UMLBOT_BROKER or mqtt://127.0.0.1:1883).")
@click.option("--ca-file", type=click.Path(dir_okay=False, path_type=Path), default=None,
              help="CA certificate file for mqtts:// brokers.")
@click.option("--robot", default=None, metavar="ID", help="Robot id (default: $UMLBOT_ROBOT or car).")
@click.option("--domain-id", type=click.IntRange(0, 232), default=None,
              help="ROS 2 domain (default: $ROS_DOMAIN_ID or 0).")
@click.option("--call-timeout", default=2.0, show_default=True, type=seconds(0.01),
              help="Seconds a feature call through /umlbot/<robot>/call waits by default.")
@click.option("--connect-timeout", default=10.0, show_default=True, type=seconds(0.1),
              help="Seconds to wait for the broker at start-up.")
def command(broker_url: str | None, ca_file: Path | None, robot: str | None, domain_id: int | None,
            call_timeout: float, connect_timeout: float) -> None:
    """Publish the robot's status, states and trace to ROS 2 and serve its features as a ROS 2
    service."""
    from umlbot.base import sdnotify
    from umlbot.base.logs import get_logger
    from umlbot.services.bus import BrokerSettings, resolve_broker_url
    from umlbot.services.ros2.bridge import Ros2Bridge

    settings = BrokerSettings.from_url(resolve_broker_url(broker_url), ca_file=ca_file)
    domain = domain_id if domain_id is not None else int(os.environ.get("ROS_DOMAIN_ID", "0") or 0)
    log = get_logger("umlbot.ros2.bridge")
    bridge = Ros2Bridge(settings, robot or os.environ.get("UMLBOT_ROBOT") or "car", domain, call_timeout)
    with StopSignals() as signals:
        try:
            bridge.start(connect_timeout)
            signals.running()
            log.info("ros2_bridge_serving", robot=bridge.robot)  # from now on a signal stops it in order
            sdnotify.notify("READY=1")
            signals.stop.wait()
            sdnotify.notify("STOPPING=1")
        finally:
            bridge.stop()
