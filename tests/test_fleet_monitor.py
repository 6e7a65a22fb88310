"""`umlbot monitor --robot '*'` and `--robot a,b`: the robots seen on one broker (a fleet hub)."""

from __future__ import annotations

import json
import subprocess
import sys
from collections.abc import Callable

from conftest import BrokerProcess, RawClient

STATUS = '{"state":"online","impl":"l298n","features":["dutycycle"]}'


def monitor(url: str, robot: str) -> set[str]:
    done = subprocess.run(
        [sys.executable, "-c", "from umlbot.cli import main; main()", "monitor", "--broker", url,
         "--robot", robot, "--json", "--duration", "1"],
        capture_output=True, text=True, timeout=60, check=False,
    )
    assert done.returncode == 0, done.stderr[-2000:]
    events = [json.loads(line) for line in done.stdout.splitlines() if line.strip()]
    return {e["robot"] for e in events if e["type"] == "availability"}


def test_monitor_shows_every_robot_or_the_listed_ones(mosquitto_broker: BrokerProcess,
                                                       raw_client: Callable[..., RawClient]) -> None:
    publisher = raw_client(mosquitto_broker)
    for robot in ("fleet-a", "fleet-b", "fleet-c"):
        publisher.publish(f"umlbot/{robot}/LeftActuator/status", STATUS, retain=True)
    try:
        assert {"fleet-a", "fleet-b", "fleet-c"} <= monitor(mosquitto_broker.url, "*")
        assert monitor(mosquitto_broker.url, "fleet-a, fleet-c") == {"fleet-a", "fleet-c"}
    finally:
        for robot in ("fleet-a", "fleet-b", "fleet-c"):
            publisher.publish(f"umlbot/{robot}/LeftActuator/status", "", retain=True)
