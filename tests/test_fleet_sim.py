"""`umlbot sim MODEL --robots N`: N cars, each on its own leaf Mosquitto bridged to a hub."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent
MODEL = REPO / "models" / "robot_car" / "model.yaml"


def umlbot(*args: str, timeout: float = 180) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-c", "from umlbot.cli import main; main()", *args],
                          capture_output=True, text=True, timeout=timeout, check=False)


def test_two_cars_each_reach_the_goal_as_their_own_robot() -> None:
    done = umlbot("sim", str(MODEL), "--robots", "2", "--robot", "bot", "--track", "left_bend",
                  "--speed", "10", "--json")
    assert done.returncode == 0, done.stderr[-2000:]
    report = json.loads(done.stdout.strip().splitlines()[-1])
    assert report["hub"].startswith("mqtt://127.0.0.1:")
    assert sorted(report["robots"]) == ["bot1", "bot2"]
    for robot in report["robots"].values():
        assert robot["exit_code"] == 0 and robot["summary"]["goal"] and robot["summary"]["actions"] > 10


def test_robots_refuses_a_broker_of_its_own() -> None:
    done = umlbot("sim", str(MODEL), "--robots", "2", "--broker", "mqtt://127.0.0.1:1")
    assert done.returncode == 2
    assert "--robots runs its own brokers and many cars: not with --broker" in done.stderr
