"""ROS 2 components against independent peers over real DDS on loopback: a Fast DDS program
(ROS 2's default DDS, tests/ros2_peer) publishes `sensor_msgs/msg/Range` and subscribes
`geometry_msgs/msg/Twist`; a Cyclone DDS process serves std_srvs services in rmw_cyclonedds'
layout. Messages on the Fast DDS side are encoded and decoded by rosbags, not by umlbot's code.
umlbot's side runs as the `ros2` service on a real broker and is called over MQTT."""

from __future__ import annotations

import json
import subprocess
import sys
import threading
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from conftest import BrokerProcess, RawClient
from ros2_support import FastDdsPeer, build_peer, message, session_domain
from services_support import ROBOT, StateWatch, client, running

from umlbot.base.deployment import Deployment
from umlbot.base.errors import RemoteError
from umlbot.services.bus import Topics

pytestmark = pytest.mark.network

DOMAIN = session_domain()
RANGE = "sensor_msgs/msg/Range"
TWIST = "geometry_msgs/msg/Twist"


@pytest.fixture(scope="module")
def peer_exe() -> Path:
    return build_peer()


@pytest.fixture
def peer(peer_exe: Path) -> Iterator[FastDdsPeer]:
    process = FastDdsPeer(peer_exe, DOMAIN)
    try:
        yield process
    finally:
        process.close()


def ros2_deployment(**components: dict[str, Any]) -> Deployment:
    return Deployment.model_validate({"robot": ROBOT, "driver": "dds", "components": {
        name: {"impl": spec.pop("impl"), "settings": {"domain_id": DOMAIN, **spec}}
        for name, spec in components.items()}})


def _until(predicate: Any, timeout: float = 10.0) -> Any:
    deadline = time.monotonic() + timeout
    while True:
        result = predicate()
        if result is not None or time.monotonic() > deadline:
            return result
        time.sleep(0.05)


def test_range_from_fast_dds_is_value_in_cm(mosquitto_broker: BrokerProcess, peer: FastDdsPeer) -> None:
    dep = ros2_deployment(Front={"impl": "ros2_range", "topic": "/front/range", "stale_s": 0.5,
                                 "first_s": 0.2})
    with running("ros2", dep, mosquitto_broker.url), client(mosquitto_broker.url) as bus:
        with pytest.raises(RemoteError) as caught:
            bus.call("Front", "value")
        assert caught.value.code == "no_reading"
        assert "no sensor_msgs/msg/Range on /front/range yet" in caught.value.message

        def reading(range_m: float) -> int | None:
            peer.publish("/front/range", RANGE, message(RANGE, range=range_m, max_range=4.0, min_range=0.02))
            try:
                value: int = bus.call("Front", "value")
            except RemoteError:
                return None
            return value

        assert _until(lambda: reading(1.234)) == 123, "metres -> centimetres, rounded"
        peer.publish("/front/range", RANGE, message(RANGE, range=0.456, max_range=4.0))
        assert _value_becomes(bus, 46)
        peer.publish("/front/range", RANGE, message(RANGE, range=float("inf"), max_range=4.0))
        assert _value_becomes(bus, 400), "+inf (REP 117: nothing in range) answers max_range"
        time.sleep(0.6)  # the reading ages past stale_s
        with pytest.raises(RemoteError) as caught:
            bus.call("Front", "value")
        assert caught.value.code == "stale" and "stale after 0.5 s" in caught.value.message


def test_drive_and_stop_reach_a_fast_dds_twist_subscriber(
    mosquitto_broker: BrokerProcess, peer: FastDdsPeer, raw_client: Any
) -> None:
    peer.subscribe("/cmd_vel", TWIST)
    dep = ros2_deployment(Base={"impl": "ros2_twist", "topic": "/cmd_vel"})
    with running("ros2", dep, mosquitto_broker.url), client(mosquitto_broker.url) as bus:
        watch = StateWatch(bus, "Base")

        def sent() -> Any:
            bus.call("Base", "drive", 0.5, -1.25)
            try:
                return peer.next_message("/cmd_vel", TWIST, timeout=0.3)
            except TimeoutError:
                return None

        twist = _until(sent)
        assert twist is not None, "the Fast DDS peer never got a Twist"
        assert (twist.linear.x, twist.linear.y, twist.linear.z) == (0.5, 0.0, 0.0)
        assert (twist.angular.x, twist.angular.y, twist.angular.z) == (0.0, 0.0, -1.25)
        watch.wait("Base", lambda s: s.get("drive", {}).get("value") == {"linear_mps": 0.5,
                                                                         "angular_rps": -1.25})
        with pytest.raises(RemoteError) as caught:
            bus.call("Base", "drive", 9.0, 0.0)
        assert caught.value.code == "out_of_range"
        bus.call("Base", "stop")
        twist = _drain_to_last(peer)
        assert (twist.linear.x, twist.angular.z) == (0.0, 0.0)

        # the fail-safe: the orchestrator's last will says offline -> the base is stopped
        bus.call("Base", "drive", 0.3, 0.0)
        assert _drain_to_last(peer).linear.x == 0.3
        raw: RawClient = raw_client(mosquitto_broker)
        raw.publish(Topics(ROBOT).orchestrator_status, json.dumps({"state": "offline"}), retain=True)
        twist = peer.next_message("/cmd_vel", TWIST, timeout=5)
        assert (twist.linear.x, twist.angular.z) == (0.0, 0.0), "stopped when the orchestrator went away"
        raw.publish(Topics(ROBOT).orchestrator_status, "", retain=True)
    # and when the service stops
    twist = peer.next_message("/cmd_vel", TWIST, timeout=5)
    assert (twist.linear.x, twist.angular.z) == (0.0, 0.0)


def _drain_to_last(peer: FastDdsPeer) -> Any:
    last = peer.next_message("/cmd_vel", TWIST, timeout=5)
    while True:
        try:
            last = peer.next_message("/cmd_vel", TWIST, timeout=0.2)
        except TimeoutError:
            return last


def test_garbage_and_wrong_types_are_no_reading(mosquitto_broker: BrokerProcess, peer: FastDdsPeer) -> None:
    dep = ros2_deployment(Front={"impl": "ros2_range", "topic": "/front/range", "first_s": 0.3})
    with running("ros2", dep, mosquitto_broker.url), client(mosquitto_broker.url) as bus:
        # the right type name with bytes that are no Range (a string length far past the sample):
        # Cyclone's own deserialiser drops them (and says so on stderr)
        for _ in range(5):
            peer.publish_raw("/front/range", "sensor_msgs::msg::dds_::Range_",
                             bytes.fromhex("00010000ffffff7f"))
            time.sleep(0.05)
        # another type on the same topic: DDS does not match it
        peer.publish("/front/range", "std_msgs/msg/String", message("std_msgs/msg/String", data="1.0"))
        with pytest.raises(RemoteError) as caught:
            bus.call("Front", "value")
        assert caught.value.code == "no_reading"
        # the component still works once a good Range comes
        peer.publish("/front/range", RANGE, message(RANGE, range=0.5))
        assert _until(lambda: _value_or_none(bus, "Front")) == 50


def _value_becomes(bus: Any, expected: int) -> bool:
    return _until(lambda: True if _value_or_none(bus, "Front") == expected else None, 5) is True


def _value_or_none(bus: Any, component: str) -> Any:
    try:
        return bus.call(component, "value")
    except RemoteError:
        return None


CYCLONE_SERVER = """
import sys, time
from umlbot.services.ros2.msgtypes import Types
from umlbot.services.ros2 import dds
domain, delay = int(sys.argv[1]), float(sys.argv[2])
builder = dds.TypeBuilder.of(Types.load())
def set_bool(request):
    print("request", request.data, flush=True)
    time.sleep(delay)
    response = server.response()
    response.success, response.message = request.data, f"lamp {'on' if request.data else 'off'}"
    return response
def trigger(request):
    response = server2.response()
    response.success, response.message = True, "triggered"
    return response
server = dds.ServiceServer(builder, domain, "/lamp/set", "std_srvs/srv/SetBool", set_bool)
server2 = dds.ServiceServer(builder, domain, "/lamp/blink", "std_srvs/srv/Trigger", trigger)
print("ready", flush=True)
sys.stdin.read()
"""


def _cyclone_server(delay: float) -> subprocess.Popen[str]:
    process = subprocess.Popen([sys.executable, "-c", CYCLONE_SERVER, str(DOMAIN), str(delay)],
                               stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True)
    assert process.stdout is not None
    assert process.stdout.readline().strip() == "ready"
    return process


def test_setbool_and_trigger_through_a_cyclone_dds_server(mosquitto_broker: BrokerProcess) -> None:
    server = _cyclone_server(0.0)
    dep = ros2_deployment(Lamp={"impl": "ros2_setbool", "service": "/lamp/set", "timeout_s": 5},
                          Blink={"impl": "ros2_trigger", "service": "/lamp/blink", "timeout_s": 5})
    try:
        with running("ros2", dep, mosquitto_broker.url), client(mosquitto_broker.url) as bus:
            watch = StateWatch(bus, "Lamp")
            assert bus.call("Lamp", "set", True, timeout=6) is True
            assert watch.wait("Lamp", lambda s: "set" in s)["set"] == {"value": True, "message": "lamp on"}
            assert bus.call("Lamp", "set", False, timeout=6) is False, "the response's success"
            assert bus.call("Blink", "trigger", timeout=6) is True
    finally:
        server.kill()
        server.wait()


def test_a_server_that_vanishes_mid_call_is_a_timeout(mosquitto_broker: BrokerProcess) -> None:
    server = _cyclone_server(30.0)
    dep = ros2_deployment(Lamp={"impl": "ros2_setbool", "service": "/lamp/set", "timeout_s": 1.5},
                          Gone={"impl": "ros2_trigger", "service": "/nobody/home", "timeout_s": 0.5})
    box: dict[str, Any] = {}
    try:
        with running("ros2", dep, mosquitto_broker.url), client(mosquitto_broker.url) as bus:

            def call() -> None:
                try:
                    box["value"] = bus.call("Lamp", "set", True, timeout=5)
                except Exception as exc:
                    box["error"] = exc

            thread = threading.Thread(target=call)
            thread.start()
            assert server.stdout is not None
            assert server.stdout.readline().startswith("request True"), "the request arrived"
            server.kill()
            thread.join(5)
            error = box.get("error")
            assert isinstance(error, RemoteError), box
            assert error.code == "timeout" and "service /lamp/set did not reply within 1.5 s" in error.message
            with pytest.raises(RemoteError) as caught:  # no server at all
                bus.call("Gone", "trigger", timeout=5)
            assert caught.value.code == "timeout"
            assert "no ROS 2 server for service /nobody/home (std_srvs/srv/Trigger)" in caught.value.message
    finally:
        server.kill()
        server.wait()


def test_signals_to_and_from_ros2_topics_with_the_orchestrator(
    mosquitto_broker: BrokerProcess, peer: FastDdsPeer
) -> None:
    from orchestrator_support import rig, wait_for

    float64 = "std_msgs/msg/Float64"
    peer.subscribe("/done", float64)
    peer.subscribe("/cmd_vel", TWIST)
    domain = {"domain_id": DOMAIN}
    with rig(mosquitto_broker.url, "ros2_signals.yaml", settings={"Base": domain, "Topics": domain}) as r:
        service: Any = r.host_of("Topics").services["Topics"]
        assert wait_for(lambda: service.signal_writers["done"].matched() > 0, 10.0), \
            "the /done writer never found the peer's reader (DDS drops what no reader matched)"
        running = r.start()
        orch = running.orchestrator
        assert wait_for(lambda: orch.signals.waiting("go") == 1, 10.0), "the accept node never waited"
        # until the peer's writer and umlbot's reader have found each other
        def go_taken() -> bool:
            peer.publish("/go", float64, message(float64, data=0.25))
            return orch.signals.waiting("go") == 0

        assert wait_for(go_taken, 10.0, 0.1), "go never arrived"
        assert running.wait(10) == 0
        done = peer.next_message("/done", float64)
        assert done.data == 0.5, "the send node's payload, on the ROS 2 topic"
        twist = peer.next_message("/cmd_vel", TWIST)
        while twist.linear.x == 0.0:  # the orchestrator's stop at its start
            twist = peer.next_message("/cmd_vel", TWIST)
        assert (twist.linear.x, twist.angular.z) == (0.25, 0.0), "the payload reached the base"
