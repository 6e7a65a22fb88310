"""The execution semantics, one small model per node kind and rule, over both real brokers.

Every model runs against mock services (in-process `ServiceHost`s) through a real broker; the
assertions read the trace events and the commands the mock drivers recorded.
"""

from __future__ import annotations

import time

import pytest
from conftest import BrokerProcess
from orchestrator_support import rig

pytestmark = pytest.mark.network


def test_fork_runs_both_calls_at_once_and_join_continues_once(broker: BrokerProcess) -> None:
    with rig(broker.url, "fork.yaml") as r:
        code, orch = r.run()
        assert code == 0, orch.failure
        actions = {e["node"]: e for e in r.trace(kind="action")}
        assert set(actions) == {"left", "right"}
        # both 100 ms calls were in flight at once: the fork region took well under 200 ms
        first_start = min(e["start"] for e in actions.values())
        last_end = max(e["end"] for e in actions.values())
        assert last_end - first_start < 0.18, actions
        assert all(e["duration_ms"] >= 95 for e in actions.values())
        assert r.nodes().count("joined") == 1
        assert r.nodes().count("after") == 1
        assert r.driver("LeftActuator").commands_named("set_duty_cycle") == [(10,)]
        assert r.driver("RightActuator").commands_named("set_duty_cycle") == [(20,)]
        assert orch.engine.stores["RaspberryPI"] == {"began": 1, "done": True}
