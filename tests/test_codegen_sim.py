"""`umlbot sim --engine cpp`: the generated program drives the car to the goal in the simulator."""

from __future__ import annotations

import pytest
from codegen_support import TEST_MODELS, built_programs

from umlbot.sim import SimOptions, find_track, run_sim

pytestmark = [pytest.mark.network, pytest.mark.timeout(600)]


def test_the_generated_program_reaches_the_goal_of_the_corridor() -> None:
    program = built_programs()["robot_car"]
    result = run_sim(SimOptions(model=TEST_MODELS["robot_car"], track=find_track("corridor"), speed=2.0,
                                port=0, timeout_s=60.0, engine="cpp", program=program))
    assert result.reason == "goal", result.as_dict()
    assert result.goal_reached and result.collisions == 0 and result.failure is None
    assert result.actions > 20  # the program's feature calls, read from its trace
    assert result.action_p50_ms is not None and result.action_p50_ms > 0


def test_an_unknown_engine_is_refused() -> None:
    from umlbot.base.errors import SimError

    with pytest.raises(SimError, match="--engine must be python or cpp"):
        run_sim(SimOptions(model=TEST_MODELS["robot_car"], track=find_track("corridor"), port=0,
                           engine="java"))
