"""bench/chaos.py, run small: the robot car's real processes under broker crashes, killed and
frozen services and malformed payloads (the full run's figures are in docs/performance.md)."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path
from typing import Any

import pytest

pytestmark = [pytest.mark.network, pytest.mark.slow]

REPO = Path(__file__).resolve().parent.parent


def chaos(*args: str, timeout: float = 110) -> dict[str, Any]:
    result = subprocess.run([sys.executable, str(REPO / "bench" / "chaos.py"), *args],
                            capture_output=True, text=True, timeout=timeout, check=False)
    assert result.returncode == 0, result.stderr[-4000:]
    summary: dict[str, Any] = json.loads(result.stdout.strip().splitlines()[-1])
    return summary


@pytest.mark.parametrize("broker", ["mosquitto", "amqtt"])
def test_a_broker_crash_stops_the_motors_and_everything_comes_back(broker: str) -> None:
    [restart] = chaos("--scenarios", "restart", "--brokers", broker, "--trials", "2")["restart"]
    assert restart["motors_stopped_every_trial"], restart["rows"]
    assert all(row["stop_reasons"] == ["broker connection lost"] for row in restart["rows"])
    assert restart["orchestrator_failed_safe_every_trial"], restart["rows"]
    assert restart["back_online_every_trial"] and restart["lost_motor_states"] == 0
    assert restart["lost_runs"] == 2  # the documented fail-safe: a run does not survive the broker


def test_killed_and_frozen_services_fail_the_run_safe() -> None:
    rows = chaos("--scenarios", "kill", "--brokers", "mosquitto", "--kinds", "motor,gpio",
                 "--trials", "1")["kill"]
    by = {(row["kind"], row["signal"]): row for row in rows}
    for signal in ("SIGKILL", "SIGSTOP"):
        assert by[("motor", signal)]["failed_safe"] == 1, by[("motor", signal)]
        # the car's model never calls the gpio component: losing it must not stop the run
        assert by[("gpio", signal)]["run_unaffected"] == 1, by[("gpio", signal)]
    assert "went offline" in by[("motor", "SIGKILL")]["reasons"][0]
    frozen = by[("motor", "SIGSTOP")]
    assert frozen["calls_timed_out"] == 1 and "no reply" in frozen["reasons"][0]
    assert frozen["motors_stopped_after_sigcont"]


@pytest.mark.parametrize("broker", ["mosquitto", "amqtt"])
def test_fuzzed_payloads_get_error_replies_and_break_nothing(broker: str) -> None:
    [fuzz] = chaos("--scenarios", "fuzz", "--brokers", broker, "--fuzz", "400", "--seed", "7")["fuzz"]
    assert fuzz["calls"] > 300 and fuzz["signals"] > 0 and fuzz["exit"] > 0
    assert fuzz["process_exits"] == 0 and fuzz["tracebacks"] == 0
    assert fuzz["requests_naming_a_reply_topic"] > 100
    assert fuzz["replies"] == fuzz["error_replies"] == fuzz["requests_naming_a_reply_topic"]
    assert fuzz["rss_growth_max_mb"] <= 5.0, fuzz["rss_growth_mb"]
    assert fuzz["good_calls_after"] and fuzz["run_still_going"]


def test_a_short_soak_samples_every_long_running_process() -> None:
    # the full soak is the benchmark (10 minutes a broker, after a 5-minute warm-up in which the
    # studio's trace history fills: docs/performance.md); this one checks that every process runs
    # and is measured, that calls, trace and page frames flow, and that the mock services, which
    # grew with every call (~8.5 MB a minute at this pace), no longer do
    [soak] = chaos("--scenarios", "soak", "--brokers", "mosquitto", "--soak-s", "30", "--soak-warmup-s", "10",
                   "--soak-sample-s", "2", "--soak-max-growth-mb", "200")["soak"]
    assert set(soak["processes"]) == {"broker", "services", "orchestrator", "monitor", "studio"}
    assert soak["process_exits"] == 0 and soak["tracebacks"] == 0, soak
    assert soak["orchestrator_state"] == "running" and soak["actions"] > 1000, soak
    assert soak["page_error"] is None and soak["page_events"]["trace"] > 1000, soak
    assert soak["page_events"]["call"] > 1000, soak
    for name, trend in soak["processes"].items():
        assert 0 < trend["first_mb"] <= trend["peak_mb"], (name, trend)
    assert soak["processes"]["services"]["growth_mb"] < 1.0, soak["processes"]


def test_a_frozen_or_killed_motor_service_no_longer_leaves_the_motors_running() -> None:
    rows = chaos("--scenarios", "frozen-motor", "--brokers", "mosquitto", "--trials", "1",
                 timeout=170)["frozen_motor"]
    by = {(row["deadman"], row["signal"]): row for row in rows}
    for signal in ("SIGSTOP", "SIGKILL"):
        with_deadman, baseline = by[(True, signal)], by[(False, signal)]
        assert with_deadman["within_watchdog"] and with_deadman["stop_max_s"] <= 2.01, with_deadman
        assert baseline["ran_the_whole_pause"] == 1, baseline  # what a frozen service did before
    assert by[(True, "SIGSTOP")]["stop_reasons_after_sigcont"] == ["deadman"]


def test_a_frozen_service_is_announced_offline_within_its_keepalive() -> None:
    """The embedded broker enforces keep-alive: a SIGSTOPped service's will goes out within
    1.5 x 5 s (it never did), and the service is back online after SIGCONT."""
    [row] = chaos("--scenarios", "keepalive", "--brokers", "amqtt", "--trials", "1")["keepalive"]
    assert row["will_published"] == 1, row
    assert row["will_after_max_s"] <= 1.5 * row["keepalive_s"] + 2.0, row
    assert row["back_online_after_sigcont"] == 1, row


def test_no_client_id_travels_on_the_bus() -> None:
    """The takeover scenario: a spy on `umlbot/<robot>/#` learns none of the fleet's client ids."""
    [row] = chaos("--scenarios", "takeover", "--brokers", "mosquitto", "--listen", "2")["takeover"]
    assert row["fleet_client_ids"] >= 6 and row["messages_heard"] > 20, row
    assert row["client_ids_on_bus"] == 0 and row["id_like_strings_on_bus"] == [], row
    # given the id, a client without a user takes the service's place: the run fails safe and
    # the service is back at once (docs/security.md: hence users on every reachable broker)
    assert row["intruder_accepted"] and row["run_failed"] and row["service_online_after_s"] is not None, row
