"""The robot seen from ROS 2: the bridge carries the orchestrator's status, the sonar's state as
`sensor_msgs/msg/Range` and the trace to a Fast DDS peer, and serves feature calls as the ROS 2
service `/umlbot/<robot>/call` (called here by a Cyclone DDS client in rmw_cyclonedds' layout)."""

from __future__ import annotations

import json
import time
from collections.abc import Iterator
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path
from typing import Any

import pytest
from conftest import BrokerProcess, RawClient
from ros2_support import FastDdsPeer, build_peer, session_domain
from services_support import ROBOT, client, deployment, running

from umlbot.base.library import FeatureSpec, Param
from umlbot.services.bus import BrokerSettings, ComponentServer, Feature, Topics
from umlbot.services.ros2 import dds
from umlbot.services.ros2.bridge import Ros2Bridge
from umlbot.services.ros2.msgtypes import Types

pytestmark = pytest.mark.network
DOMAIN = session_domain()


@pytest.fixture
def peer() -> Iterator[FastDdsPeer]:
    process = FastDdsPeer(build_peer(), DOMAIN)
    try:
        yield process
    finally:
        process.close()


def _until(peer: FastDdsPeer, topic: str, typename: str, poke: Any, timeout: float = 10.0) -> Any:
    """Poke (publish on MQTT) until the peer receives a message on `topic`."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        poke()
        try:
            return peer.next_message(topic, typename, timeout=0.3)
        except TimeoutError:
            continue
    raise AssertionError(f"nothing on {topic} within {timeout} s")


def test_status_range_and_trace_reach_a_fast_dds_peer(
    mosquitto_broker: BrokerProcess, raw_client: Any, peer: FastDdsPeer
) -> None:
    base = f"/umlbot/{ROBOT}"
    peer.subscribe(f"{base}/orchestrator/status", "umlbot_msgs/msg/OrchestratorStatus")
    peer.subscribe(f"{base}/DistanceRead/range", "sensor_msgs/msg/Range")
    peer.subscribe(f"{base}/orchestrator/trace", "umlbot_msgs/msg/TraceEvent")
    topics = Topics(ROBOT)
    raw: RawClient = raw_client(mosquitto_broker)
    dep = deployment(DistanceRead={"mock_distances": [123]})
    settings = BrokerSettings.from_url(mosquitto_broker.url)
    with Ros2Bridge(settings, ROBOT, DOMAIN), running("sonar", dep, mosquitto_broker.url) as host, \
            client(mosquitto_broker.url) as bus:
        status = _until(peer, f"{base}/orchestrator/status", "umlbot_msgs/msg/OrchestratorStatus",
                        lambda: raw.publish(topics.orchestrator_status,
                                            json.dumps({"state": "running", "model": "car"})))
        assert (status.state, status.model) == ("running", "car")
        assert json.loads(status.status_json) == {"state": "running", "model": "car"}
        assert status.stamp.sec > 1_700_000_000

        sensor = host.drivers["DistanceRead"]
        readings = iter([123, 124] * 50)  # the state is published when it changes

        def ping() -> None:
            sensor.set_distance(next(readings))
            bus.call("DistanceRead", "value")

        rng = _until(peer, f"{base}/DistanceRead/range", "sensor_msgs/msg/Range", ping)
        assert round(rng.range * 100) in (123, 124) and rng.header.frame_id == "DistanceRead"
        assert (rng.min_range, rng.max_range) == (pytest.approx(0.02), pytest.approx(4.0))
        sensor.set_distance(None)
        bus.call("DistanceRead", "value")  # no echo: REP 117's +inf
        rng = peer.next_message(f"{base}/DistanceRead/range", "sensor_msgs/msg/Range")
        while rng.range != float("inf"):
            rng = peer.next_message(f"{base}/DistanceRead/range", "sensor_msgs/msg/Range")

        event = {"lane": "Main", "node": "go", "kind": "action", "start": 1.0, "end": 1.5,
                 "duration_ms": 500.0, "value": {"a": 1}, "seq": 7}
        trace = _until(peer, f"{base}/orchestrator/trace", "umlbot_msgs/msg/TraceEvent",
                       lambda: raw.publish(topics.orchestrator_trace, json.dumps([event])))
        assert (trace.seq, trace.lane, trace.node, trace.duration_ms) == (7, "Main", "go", 500.0)
        assert json.loads(trace.value_json) == {"a": 1}


def test_a_ros2_client_calls_features_through_the_bridge(mosquitto_broker: BrokerProcess) -> None:
    dep = deployment(DistanceRead={"mock_distances": [42]})
    settings = BrokerSettings.from_url(mosquitto_broker.url)
    builder = dds.TypeBuilder.of(Types.load())
    with Ros2Bridge(settings, ROBOT, DOMAIN), running("sonar", dep, mosquitto_broker.url):
        caller = dds.ServiceClient(builder, DOMAIN, f"/umlbot/{ROBOT}/call", "umlbot_msgs/srv/CallFeature")
        try:
            def call(component: str, feature: str, args: str = "") -> Any:
                request = caller.request()
                request.component, request.feature, request.args_json = component, feature, args
                return caller.call(request, 5.0)

            reply = call("DistanceRead", "value")
            assert (reply.ok, reply.value_json, reply.error_code) == (True, "42", "")
            reply = call("DistanceRead", "value", "[1]")
            assert (reply.ok, reply.error_code) == (False, "bad_args")
            reply = call("DistanceRead", "warp")
            assert not reply.ok and reply.error_code in ("unknown_feature", "timeout"), reply
            reply = call("DistanceRead", "value", "[not json")
            assert (reply.ok, reply.error_code) == (False, "bad_request")
            request = caller.request()  # nobody serves it: the sweeper answers at the time-out
            request.component, request.feature, request.timeout_s = "Nobody", "value", 0.3
            started = time.monotonic()
            reply = caller.call(request, 5.0)
            assert (reply.ok, reply.error_code) == (False, "timeout"), reply
            assert "Nobody.value" in reply.error_message and 0.3 <= time.monotonic() - started < 2.0
            assert call("DistanceRead", "value").value_json == "42", "and the bridge goes on"
        finally:
            caller.close()


def test_the_bridge_command_starts_and_stops(mosquitto_broker: BrokerProcess, tmp_path: Path) -> None:
    import subprocess
    import sys

    process = subprocess.Popen(
        [sys.executable, "-c", "from umlbot.cli import main; main()", "ros2-bridge", "--broker",
         mosquitto_broker.url, "--robot", ROBOT, "--domain-id", str(DOMAIN)],
        stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True)
    try:
        assert process.stdout is not None
        deadline = time.monotonic() + 20
        started = False
        while time.monotonic() < deadline:
            line = process.stdout.readline()
            if "ros2_bridge_serving" in line:
                started = True
                break
        assert started, "the bridge never said it started"
        process.terminate()
        code = process.wait(10)
        assert code == 0, process.stdout.read()
    finally:
        if process.poll() is None:
            process.kill()
            process.wait()


def test_a_call_in_flight_when_the_broker_goes_is_answered_not_connected(
    mosquitto_broker: BrokerProcess,
) -> None:
    settings = BrokerSettings.from_url(mosquitto_broker.url)
    builder = dds.TypeBuilder.of(Types.load())
    def nap(seconds: float) -> float:
        time.sleep(seconds)
        return seconds

    slow = ComponentServer(settings, ROBOT, "Slow", "test", [
        Feature(FeatureSpec("nap", (Param("seconds", "float", 0, 5),), "float"), nap)])
    slow.start(5.0)
    try:
        with Ros2Bridge(settings, ROBOT, DOMAIN):
            caller = dds.ServiceClient(builder, DOMAIN, f"/umlbot/{ROBOT}/call",
                                       "umlbot_msgs/srv/CallFeature")
            try:
                assert caller.wait_for_server(10.0)
                request = caller.request()
                request.component, request.feature, request.args_json = "Slow", "nap", "[0.05]"
                reply = caller.call(request, 5.0)
                assert (reply.ok, reply.value_json) == (True, "0.05")  # answered by its reply
                request = caller.request()
                request.component, request.feature, request.args_json = "Slow", "nap", "[3]"
                request.timeout_s = 10.0
                with ThreadPoolExecutor(1) as pool:
                    pending = pool.submit(caller.call, request, 8.0)
                    time.sleep(0.5)
                    started = time.monotonic()
                    mosquitto_broker.stop()
                    reply = pending.result(8.0)
                # answered when the connection went, not at the call's time-out (10 s)
                assert (reply.ok, reply.error_code) == (False, "not_connected"), reply
                assert time.monotonic() - started < 2.5
            finally:
                caller.close()
    finally:
        slow.stop()
