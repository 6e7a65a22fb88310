"""What a long-running process records is bounded (issue 23 §3): mock drivers' command records,
the monitor's tables and statistics, the studio hub's tables. Each test drives many times more
than the bound through the real code and checks that the bound holds and the newest is kept;
how flat the processes' memory stays over time is measured by `bench/chaos.py --scenarios soak`."""

from __future__ import annotations

import io
import json
import tracemalloc
from typing import Any

import pytest
from rich.console import Console

from umlbot.base.bounded import MAX_ROWS
from umlbot.base.registry import SettingsError, create_driver
from umlbot.monitor import MonitorState, Stats, render
from umlbot.services.mock_support import DEFAULT_RECORD
from umlbot.studio.hub import KEEP_CALLS, Hub

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


# --- the monitor (also the studio's source of calls and statistics) --------------------------


def _trace(lane: str, node: str, duration_ms: float) -> bytes:
    return json.dumps({"lane": lane, "node": node, "kind": "action", "start": 0.0, "end": 1.0,
                       "duration_ms": duration_ms, "detail": f"{node}()"}).encode()


def test_the_monitor_tables_keep_at_most_max_rows_and_the_busy_ones() -> None:
    state = MonitorState()
    flood = 3 * MAX_ROWS
    for i in range(flood):
        # the car's real rows are updated all along; a flood of one-off names goes past them
        state.observe("umlbot/car/orchestrator/trace", _trace("Left", "drive", 2.0), 1.0)
        state.observe("umlbot/car/LeftActuator/call/dutycycle", b"[60]", 1.0)
        state.observe("umlbot/car/LeftActuator/status", b'{"state": "online"}', 1.0)
        state.observe("umlbot/car/orchestrator/status", b'{"state": "running"}', 1.0)
        state.observe("umlbot/car/orchestrator/trace", _trace(f"lane{i}", f"node{i}", 1.0), 1.0)
        state.observe(f"umlbot/car/Junk{i}/call/f{i}", b"[1]", 1.0)
        state.observe(f"umlbot/car/Junk{i}/status", b'{"state": "online"}', 1.0)
        state.observe(f"umlbot/robot{i}/orchestrator/status",
                      b'{"state": "running", "call_timeout_s": 2}', 1.0)
    for table in (state.actions, state.features, state.lanes, state.availability, state.orchestrator,
                  state.robot_call_timeouts):
        assert len(table) == MAX_ROWS
    # five tables hold a car's row and the flood, one only the flood; the car's rows never went
    assert state.dropped_rows == 5 * (flood + 1 - MAX_ROWS) + (flood - MAX_ROWS)
    assert state.actions[("car", "Left", "drive")].count == flood
    assert state.features[("car", "LeftActuator", "dutycycle")].count == flood
    assert state.availability[("car", "LeftActuator")].state == "online"
    assert state.orchestrator["car"] == "running"
    assert ("car", f"lane{flood - 1}", f"node{flood - 1}") in state.actions  # the newest stays
    assert ("car", "lane0", "node0") not in state.actions
    assert f"{state.dropped_rows} rows dropped" in _text(state)


def _text(state: MonitorState) -> str:
    console = Console(file=io.StringIO(), width=200, record=True)
    console.print(render(state, now=2.0))
    return console.export_text()


def _held_bytes(build: Any) -> int:
    tracemalloc.start()
    try:
        before = tracemalloc.get_traced_memory()[0]
        kept = build()
        held = tracemalloc.get_traced_memory()[0] - before
    finally:
        tracemalloc.stop()
    assert kept is not None
    return held


def test_a_monitor_row_holds_percentiles_of_the_whole_run_in_a_few_kilobytes() -> None:
    def feed(n: int) -> Stats:
        stats = Stats("drive")
        for i in range(n):  # 1 µs to 10 s: the widest spread a row sees
            stats.add(0.001 * 10 ** (7 * ((i * 7919) % n) / n))
        return stats

    small, large = _held_bytes(lambda: feed(1000)), _held_bytes(lambda: feed(100_000))
    assert large < 64_000 and large < small + 32_000, (small, large)
    # the whole run counts, not a window of the newest: 10 000 fast calls, then 2500 slow ones
    stats = Stats("call")
    for _ in range(10_000):
        stats.add(1.0)
    for _ in range(2500):
        stats.add(100.0)
    assert stats.p50 == pytest.approx(1.0, rel=0.01) and stats.p99 == pytest.approx(100.0, rel=0.01)


# --- the studio's hub (the snapshot a page opening later gets) ----------------------------------


def test_the_studio_hub_keeps_the_state_of_at_most_max_rows_components() -> None:
    hub = Hub(keep_trace=50)
    flood = 3 * MAX_ROWS
    for i in range(flood):
        hub.push({"type": "availability", "robot": "car", "component": "LeftActuator", "state": "online",
                  "time": float(i)})
        hub.push({"type": "state", "robot": "car", "component": "LeftActuator", "payload": {"n": i},
                  "time": float(i)})
        hub.push({"type": "availability", "robot": "car", "component": f"Junk{i}", "state": "online",
                  "time": float(i)})
        hub.push({"type": "state", "robot": "car", "component": f"Junk{i}", "payload": {}, "time": float(i)})
        hub.push({"type": "trace", "robot": "car", "lane": "L", "node": f"n{i}", "time": float(i)})
        hub.push({"type": "call", "robot": "car", "component": "LeftActuator", "feature": "dutycycle",
                  "time": float(i)})
        if i % 100 == 0:
            hub.flush()
    hub.flush()
    assert len(hub.availability) == len(hub.retained) == MAX_ROWS
    assert hub.retained["car/LeftActuator"]["payload"] == {"n": flood - 1}
    assert "car/Junk0" not in hub.availability and f"car/Junk{flood - 1}" in hub.availability
    assert len(hub.trace) == 50 and hub.trace[-1]["node"] == f"n{flood - 1}"
    assert len(hub.calls) == KEEP_CALLS
    assert len(hub.snapshot()) == 2 * MAX_ROWS + 50 + KEEP_CALLS
