"""GPIOs named by a component's settings, single pins and pin lists alike (gpio's `pins`): each
pin belongs to one component, and `umlbot check`, the service host and the gpio service's
reserved pins all read them through `umlbot.base.deployment.component_pins`."""

from __future__ import annotations

import shutil
import subprocess
import sys
from pathlib import Path

import pytest
from services_support import broker_settings

from umlbot.base.catalog import resolve_implementation
from umlbot.base.deployment import component_pins, owned_pins, parse_deployment, shared_pins
from umlbot.base.errors import ConfigError
from umlbot.services.host import ServiceHost

REPO = Path(__file__).resolve().parent.parent

TWO_GPIO = """\
driver: mock
components:
  Board:
    impl: raspberrypi
    settings: {pins: [4, 5, 6]}
  Expander:
    impl: raspberrypi
    settings: {pins: [17, 6]}
  LeftActuator:
    impl: l298n
    settings: {in1: 17, in2: 23}
"""


def test_every_pin_of_a_pin_list_is_the_components() -> None:
    gpio = resolve_implementation("raspberrypi")
    assert [(s.pin, s.key, s.path) for s in component_pins(gpio, {"pins": [4, 5], "pull": "up"})] == [
        (4, "pins", ("pins", 0)), (5, "pins", ("pins", 1))]
    motor = resolve_implementation("l298n")
    assert [s.pin for s in component_pins(motor, {"in1": 22, "in2": 23, "watchdog_s": 2})] == [22, 23]


def test_two_components_listing_one_pin_are_reported() -> None:
    dep = parse_deployment(TWO_GPIO, "deployment.yaml")
    found = [(s.pin, s.component, s.key, s.first, s.first_key, s.path) for s in shared_pins(dep)]
    assert found == [(6, "Expander", "pins", "Board", "pins", ("pins", 1)),
                     (17, "LeftActuator", "in1", "Expander", "pins", ("in1",))]
    assert shared_pins(dep)[0].message() == ("GPIO 6 ('pins' of 'Expander') is already wired to 'Board' "
                                             "('pins'): each pin belongs to one component")
    assert owned_pins(dep) == {4: "Board", 5: "Board", 6: "Board", 17: "Expander", 23: "LeftActuator"}


def test_the_service_host_refuses_a_pin_list_entry_owned_by_another_component() -> None:
    dep = parse_deployment(TWO_GPIO, "deployment.yaml")
    with pytest.raises(ConfigError, match=r"^deployment\.yaml:8:27: GPIO 6 \('pins' of 'Expander'\)"):
        ServiceHost("gpio", dep, broker_settings("mqtt://127.0.0.1:1"), "car")


def test_umlbot_check_reports_a_gpio_pin_list_entry_wired_to_a_motor(tmp_path: Path) -> None:
    model = tmp_path / "car"
    shutil.copytree(REPO / "models" / "robot_car", model)
    deployment = model / "deployment.yaml"
    text = deployment.read_text(encoding="utf-8")
    assert "settings: {pins: []}" in text
    deployment.write_text(text.replace("settings: {pins: []}", "settings: {pins: [5, 24]}"), encoding="utf-8")
    result = subprocess.run(
        [sys.executable, "-c", "from umlbot.cli import main; main()", "check", str(model)],
        capture_output=True, text=True, timeout=120, check=False)
    assert result.returncode == 1, result.stdout + result.stderr
    assert ("deployment.yaml:15:16: error: GPIO 24 ('in1' of 'RightActuator') is already wired to "
            "'RaspberryPI' ('pins'): each pin belongs to one component") in result.stdout + result.stderr
