"""A fleet: each robot's Mosquitto bridged to a hub Mosquitto; one place sees every robot.

`bridge_conf`, `hub_conf` and `hub_acl` write the Mosquitto configuration (deploy/fleet.py and
deploy/install.sh --hub use them); `LocalFleet` runs a hub and a leaf broker per robot on one
machine (`umlbot fleet`, the tests, bench/fleet.py).
"""

from umlbot.fleet.brokers import LocalFleet, Mosquitto, find_mosquitto, free_port
from umlbot.fleet.config import (
    INBOUND,
    LINK_TOPIC,
    OPERATOR,
    VIEWER,
    Hub,
    bridge_conf,
    check_robot_id,
    hub_acl,
    hub_conf,
    robot_user,
)
from umlbot.fleet.simfleet import CarResult, SimFleet, robot_ids

__all__ = [
    "INBOUND",
    "LINK_TOPIC",
    "OPERATOR",
    "VIEWER",
    "CarResult",
    "Hub",
    "LocalFleet",
    "Mosquitto",
    "SimFleet",
    "bridge_conf",
    "check_robot_id",
    "find_mosquitto",
    "free_port",
    "hub_acl",
    "hub_conf",
    "robot_ids",
    "robot_user",
]
