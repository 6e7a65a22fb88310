"""The handover from `umlbot service` to its serving process (`umlbot.services.serve`).

The command reads the deployment (PyYAML, positions) and the broker URL, then becomes `python -m
umlbot.services.serve` with them as JSON in its environment: what the serving process validates
again must be the same deployment, name the same `file:line:col` in its errors, and keep the
broker password that pydantic's own JSON hides.
"""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest
from pydantic import ValidationError

from umlbot.base.deployment import Deployment, load_deployment, parse_deployment
from umlbot.services import serve
from umlbot.services.bus import BrokerSettings

ROOT = Path(__file__).resolve().parent.parent
CAR = ROOT / "models" / "robot_car" / "deployment.yaml"

NESTED = """\
deployment:
  robot: r2
  components:
    LeftActuator:
      impl: l298n
      driver: mock
      settings:
        in1: 22
        in2: 23
        limits: [1, {deep: .inf}]
    DistanceRead: {impl: hcsr04, settings: {trigger: 8, echo: 7}}
"""

#: paths a service's errors name: existing ones, and deeper ones that stop where the file does
LEFT = ("components", "LeftActuator")
PATHS = [(), ("components",), LEFT, (*LEFT, "driver"), (*LEFT, "settings", "in2"),
         (*LEFT, "settings", "nope"), (*LEFT, "settings", "limits", 1, "deep"),
         (*LEFT, "settings", "limits", 5), ("components", "DistanceRead", "settings", "echo"),
         ("components", "Nobody", "settings"), ("driver",)]


def _handover(deployment: Deployment, broker: BrokerSettings) -> serve.Handover:
    return serve.Handover(kinds=("motor",), deployment=deployment.handover(), broker=broker, robot="r2",
                          driver=None, components=["LeftActuator"], connect_timeout_s=2.5, log_level="DEBUG",
                          log_json=True)


@pytest.mark.parametrize("source", ["nested", "car", "plain"])
def test_the_serving_process_gets_the_same_deployment_and_positions(source: str, tmp_path: Path) -> None:
    if source == "nested":
        path = tmp_path / "deploy.yaml"
        path.write_text(NESTED)
        original = load_deployment(path)
    elif source == "car":
        original = load_deployment(CAR)
    else:
        original = parse_deployment("LeftActuator=l298n\nDistanceRead=hcsr04\n", "car.txt")
    (tmp_path / "ca.pem").write_text("not read here")
    broker = BrokerSettings.from_url("mqtts://user:p%40ss@broker.local:8883?keepalive=60",
                                     ca_file=tmp_path / "ca.pem")
    back = serve.decode(serve.encode(_handover(original, broker)))
    deployment = Deployment.from_handover(back.deployment)
    # the same values (pydantic's == also compares the private positioned tree, rebuilt here)
    assert deployment.model_dump() == original.model_dump() and deployment.components == original.components
    for path_ in PATHS:
        assert deployment.where(*path_) == original.where(*path_), path_
    if source == "nested":  # positions, not just the file: line and column of the deepest value written
        assert deployment.where("components", "LeftActuator", "settings", "limits", 1, "deep") == \
            f"{tmp_path / 'deploy.yaml'}:10:22"
        assert deployment.components["LeftActuator"].settings["limits"][1]["deep"] == float("inf")
    assert back.broker == broker  # the password too (pydantic's JSON writes `**********`)
    assert back.broker.password is not None and back.broker.password.get_secret_value() == "p@ss"
    assert (back.kinds, back.robot, back.components) == (("motor",), "r2", ["LeftActuator"])
    assert back.connect_timeout_s == 2.5
    assert (back.log_level, back.log_json) == ("DEBUG", True)


def test_the_handover_is_validated_again() -> None:
    good = serve.encode(_handover(load_deployment(CAR), BrokerSettings()))
    for bad in (good.replace('"connect_timeout_s":2.5', '"connect_timeout_s":-1'),
                good.replace('"port":1883', '"port":0'), good.replace('"kinds":["motor"]', '"kinds":[]')):
        assert bad != good
        with pytest.raises(ValidationError):
            serve.decode(bad)


def test_the_serving_module_is_not_a_second_command_line() -> None:
    """Started by hand (without a handover), it says who starts it and exits 2."""
    env = {key: value for key, value in os.environ.items() if key != serve.HANDOVER_ENV}
    result = subprocess.run([sys.executable, "-m", "umlbot.services.serve", "motor"], capture_output=True,
                            text=True, env=env, timeout=60, check=False)
    assert result.returncode == 2
    assert result.stderr == "error: umlbot.services.serve is started by `umlbot service`, not by hand\n"
