"""ROS 2 topics and services as umlbot components, over DDS with ROS 2's naming (the extra
`umlbot[ros2]`: cyclonedds for the wire, rosbags for message definitions).

- `msgtypes`: ROS 2 message and service types (rosbags' definitions, std_srvs bundled, the
  user's `.msg`/`.srv` files), field paths and what values they take;
- `mapping`: a component's deployment settings: which topic or service each feature reads,
  writes or calls (checked by `umlbot check` at the settings' file:line);
- `dds`: the DDS side: loopback-only participant, types built at run time, readers, writers and
  rmw_cyclonedds-style service clients;
- `driver` and `service`: the `ros2` service kind serving such components on the bus.

Nothing here imports cyclonedds or rosbags at module import: a deployment that uses ROS 2
without the extra gets `missing_extra()`'s error.
"""

from __future__ import annotations

from umlbot.base.errors import ConfigError

EXTRA_HINT = "pip install 'umlbot[ros2]'"


def missing_extra(what: str) -> ConfigError:
    """The error for ROS 2 used without the extra installed."""
    return ConfigError(f"ROS 2 support is not installed ({what} missing): {EXTRA_HINT}")
