"""The stereo camera service over a real broker: its features on scripted depths (mock), on the
simulated world (sim driver, in this process and through the world server), a camera that stops,
and the state that says so."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest
from conftest import BrokerProcess
from services_support import ROBOT, StateWatch, client, running, sim_world

from umlbot.base.deployment import Deployment
from umlbot.base.errors import RemoteError
from umlbot.services.simworld import RemoteWorld
from umlbot.services.stereo.mock import MockStereoCamera
from umlbot.services.stereo.sim import SimStereoCamera, SimStereoSettings
from umlbot.sim.sharing import WorldServer

pytestmark = pytest.mark.network


def stereo_deployment(driver: str, **settings: Any) -> Deployment:
    return Deployment.model_validate({"robot": ROBOT, "driver": driver, "components": {
        "Eye": {"impl": "stereo_camera", "settings": {"frame_max_age_s": 0, **settings}}}})


def test_features_on_scripted_depths(broker: BrokerProcess) -> None:
    wall = [(30.0, 200.0), (10.0, 120.0), (-5.0, 80.0), (-20.0, 150.0), (-30.0, 300.0)]
    dep = stereo_deployment("mock", mock_depths=[wall, wall, wall, wall, "cameras swapped?"],
                            look_ahead_cm=60)
    with running("stereo", dep, broker.url) as host, client(broker.url) as bus:
        watch = StateWatch(bus, "Eye")
        assert bus.call("Eye", "distance", 10) == 120
        assert bus.call("Eye", "nearest") == 80
        assert bus.call("Eye", "nearestBearing") == -5
        assert bus.call("Eye", "freeWidth") > 0  # 80 cm ahead at 0°: free up to 60 cm
        state = watch.wait("Eye", lambda s: s.get("nearest_cm") == 80)
        assert state["reading"] is True and state["camera"] == "running" and state["bearing_deg"] == -5
        # a frame without any reading: -1, never a distance; the state says why
        assert bus.call("Eye", "distance", 0) == -1
        state = watch.wait("Eye", lambda s: s.get("reading") is False)
        assert state["problem"] == "cameras swapped?"
        assert bus.call("Eye", "nearest") == -1
        assert bus.call("Eye", "freeWidth") == 0
        with pytest.raises(RemoteError) as err:
            bus.call("Eye", "distance", 45)
        assert err.value.code == "out_of_range"
        camera: MockStereoCamera = host.drivers["Eye"]
        assert camera.reads == 7


def test_reach_and_open_bearing_find_the_gap_the_car_fits_through(broker: BrokerProcess) -> None:
    """A wall 80 cm ahead with a gap from 5.5° to 27.5° left (34 cm wide at the wall, a far wall
    400 cm away behind it), a wall 60 cm away on the right: the car's 24 cm strip is free far
    only through the gap, whose middle openBearing gives; a frame without a reading: -1 and 0."""
    gap = [(30, 80), (29, 80), (26, 400), (8, 400), (3, 80), (0, 80), (-30, 60)]
    dep = stereo_deployment("mock", mock_depths=[gap, gap, gap, gap, gap, gap, "too dark to see"])
    with running("stereo", dep, broker.url), client(broker.url) as bus:
        assert 70 <= bus.call("Eye", "reach", 0) <= 80  # the wall ahead
        assert bus.call("Eye", "reach", 17) >= 390  # through the gap to the far wall
        assert bus.call("Eye", "reach", 10) < 100  # the ray is in the gap, the car's width is not
        assert bus.call("Eye", "reach", -20) < 70  # the near wall on the right
        assert 14 <= bus.call("Eye", "openBearing") <= 19
        assert bus.call("Eye", "distance", 10) == 400  # a ray alone sees the gap wider than it is
        assert bus.call("Eye", "reach", 17) == -1
        assert bus.call("Eye", "openBearing") == 0
        with pytest.raises(RemoteError) as err:
            bus.call("Eye", "reach", -31)
        assert err.value.code == "out_of_range"


def test_a_camera_that_stops_delivering_frames_errors_and_says_so(broker: BrokerProcess) -> None:
    dep = stereo_deployment("mock", mock_distance_cm=90)
    with running("stereo", dep, broker.url) as host, client(broker.url) as bus:
        watch = StateWatch(bus, "Eye")
        assert bus.call("Eye", "nearest") == 90
        camera: MockStereoCamera = host.drivers["Eye"]
        camera.set_stopped(True)
        with pytest.raises(RemoteError) as err:
            bus.call("Eye", "nearest")
        assert err.value.code == "driver_error" and "no frames" in str(err.value)
        state = watch.wait("Eye", lambda s: s.get("camera") == "stopped")
        assert state["reading"] is False and "no frames" in state["problem"]
        camera.set_stopped(False)
        assert bus.call("Eye", "distance", 0) == 90
        watch.wait("Eye", lambda s: s.get("camera") == "running")


def test_sim_camera_sees_the_room_walls(broker: BrokerProcess) -> None:
    # the car in the middle of a 2 m x 3 m room facing +y: the front wall 2 m from the centre,
    # the camera 0.12 m ahead of it; a side wall 1 m to each side
    with sim_world() as world, running("stereo", stereo_deployment("sim"), broker.url), \
            client(broker.url) as bus:
        ahead = bus.call("Eye", "distance", 0)
        assert abs(ahead - 188) <= 0.03 * 188, ahead
        corner = bus.call("Eye", "distance", -25)  # toward the right: still the front wall
        assert abs(corner - 188 / 0.906) <= 0.05 * 207, corner
        world.camera_stopped = True
        with pytest.raises(RemoteError) as err:
            bus.call("Eye", "nearest")
        assert err.value.code == "driver_error"


def test_sim_camera_through_the_world_server() -> None:
    with sim_world() as world:
        server = WorldServer(world).start()
        try:
            env = server.env
            remote = RemoteWorld(env["UMLBOT_SIM_WORLD"], env["UMLBOT_SIM_KEY"])
            camera = SimStereoCamera("Eye", remote, SimStereoSettings())
            frame = camera.read_depth()
            near = [c for a, c in zip(frame.angles_deg, frame.columns_cm, strict=True)
                    if c is not None and abs(a) < 1]
            assert near and all(abs(c - 188) <= 0.03 * 188 for c in near)
            remote.close()
        finally:
            server.stop()


def test_a_stopped_camera_fails_the_stereo_car_safe(broker: BrokerProcess) -> None:
    """models/stereo_car on mock drivers: when the camera stops delivering frames, the call's error
    reply ends the run in the orchestrator's fail-safe stop, motors stopped, as for any component."""
    from orchestrator_support import rig, wait_for

    model = Path(__file__).resolve().parent.parent / "models" / "stereo_car"
    with rig(broker.url, model, settings={"Eye": {"mock_distance_cm": 150}}) as r:
        running = r.start()
        camera: MockStereoCamera = r.driver("Eye")
        motors = ("LeftActuator", "RightActuator")
        assert wait_for(lambda: camera.reads >= 2 and any(r.driver(m).running for m in motors), 15.0), \
            running.orchestrator.failure
        camera.set_stopped(True)
        assert running.wait(20.0) == 1
        failure = str(running.orchestrator.failure)
        assert "Eye" in failure and "no frames" in failure, failure
        assert not any(r.driver(m).running for m in motors)
