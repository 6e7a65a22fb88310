"""What a long-running process records is bounded (issue 23 §3): mock drivers' command records,
the monitor's tables and statistics, the studio hub's tables. Each test drives many times more
than the bound through the real code and checks that the bound holds and the newest is kept;
how flat the processes' memory stays over time is measured by `bench/chaos.py --scenarios soak`."""

from __future__ import annotations

from typing import Any

import pytest

from services.mock_support import DEFAULT_RECORD
from services.registry import SettingsError, create_driver

MOCK_CALLS: dict[str, tuple[str, dict[str, Any], str]] = {
    # kind: (method, settings, what the call records)
    "motor": ("set_duty_cycle", {}, "set_duty_cycle"),
    "servo": ("set_angle", {}, "set_angle"),
    "sonar": ("read_distance_cm", {}, "read_distance_cm"),
    "gpio": ("write", {"pins": [4]}, "write"),
}


def _call(driver: Any, kind: str, i: int) -> None:
    if kind == "motor":
        driver.set_duty_cycle(i % 101)
    elif kind == "servo":
        driver.set_angle(i % 181)
    elif kind == "sonar":
        driver.read_distance_cm()
    else:
        driver.write(4, i % 2)


@pytest.mark.parametrize("kind", sorted(MOCK_CALLS))
def test_a_mock_driver_keeps_only_the_newest_commands(kind: str) -> None:
    _, settings, method = MOCK_CALLS[kind]
    driver = create_driver(kind, "mock", "Part", settings)
    calls = 5 * DEFAULT_RECORD + 7
    for i in range(calls):
        _call(driver, kind, i)
    assert driver.recorded == calls
    assert len(driver.commands) == DEFAULT_RECORD
    assert len(driver.commands_named(method)) == DEFAULT_RECORD
    newest = driver.commands[-1]
    assert newest[0] == method
    if kind == "motor":
        assert newest[1] == ((calls - 1) % 101,)
        assert driver.commands[0][1] == ((calls - DEFAULT_RECORD) % 101,)
    driver.close()  # a safety stop and close are recorded too, the oldest calls make room
    assert driver.commands[-1] == ("close", ()) and len(driver.commands) == DEFAULT_RECORD


def test_the_mock_record_bound_is_a_setting() -> None:
    driver = create_driver("motor", "mock", "Left", {"mock_record": 3})
    for percent in (10, 20, 30, 40):
        driver.set_duty_cycle(percent)
    driver.stop()
    assert driver.commands == [("set_duty_cycle", (30,)), ("set_duty_cycle", (40,)), ("stop", ())]
    assert driver.recorded == 5
    with pytest.raises(SettingsError, match="mock_record: Input should be greater than or equal to 1"):
        create_driver("motor", "mock", "Left", {"mock_record": 0})
