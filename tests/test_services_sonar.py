"""The sonar service over real brokers: `value()` via the bus and raw payloads, no echo, state,
pigpio on the fake, a scriptable mock service in its own process, and the sim driver pinging a
simulated world."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from collections.abc import Callable
from pathlib import Path

import pytest
from conftest import BrokerProcess, RawClient
from services_support import ROBOT, StateWatch, client, deployment, raw_state, running, sim_world, wait_for

from umlbot.base.errors import RemoteError
from umlbot.services.bus import Topics
from umlbot.services.pins import pigpio as pigpio_connection
from umlbot.services.sonar.mock import MockDistanceSensor
from umlbot.sim import CarSpec
from umlbot.testing.pigpio import FakePi

pytestmark = pytest.mark.network
TOPICS = Topics(ROBOT)


def test_value_follows_the_script_and_no_echo_is_max_range(broker: BrokerProcess) -> None:
    dep = deployment(DistanceRead={"mock_distances": [100, 14.6, None, 35]})
    with running("sonar", dep, broker.url) as host, client(broker.url) as bus:
        watch = StateWatch(bus, "DistanceRead")
        assert bus.call("DistanceRead", "value") == 100
        assert bus.call("DistanceRead", "value") == 15, "centimetres, rounded to int"
        state = watch.wait("DistanceRead", lambda s: s["distance_cm"] == 15)
        assert state == {"distance_cm": 15, "echo": True}
        assert bus.call("DistanceRead", "value") == 400
        state = watch.wait("DistanceRead", lambda s: s["echo"] is False)
        assert state == {"distance_cm": 400, "echo": False}
        assert bus.call("DistanceRead", "value") == 35
        sensor: MockDistanceSensor = host.drivers["DistanceRead"]
        assert sensor.reads == 4


def test_max_range_setting_is_the_no_echo_value(mosquitto_broker: BrokerProcess) -> None:
    dep = deployment(DistanceRead={"mock_distances": [None], "max_range_cm": 250})
    with running("sonar", dep, mosquitto_broker.url), client(mosquitto_broker.url) as bus:
        assert bus.call("DistanceRead", "value") == 250


def test_raw_calls_with_and_without_reply(
    mosquitto_broker: BrokerProcess, raw_client: Callable[..., RawClient]
) -> None:
    raw = raw_client(mosquitto_broker)
    raw.subscribe("test/reply")
    raw.subscribe(TOPICS.state("DistanceRead"))
    dep = deployment(DistanceRead={"mock_distances": [42, 7]})
    with running("sonar", dep, mosquitto_broker.url):
        raw.publish(TOPICS.call("DistanceRead", "value"), "")  # bare, fire-and-forget: reads once
        assert raw_state(raw, "DistanceRead", lambda s: s["distance_cm"] == 42)["echo"] is True
        raw.publish(TOPICS.call("DistanceRead", "value"), json.dumps({"id": 7, "reply_to": "test/reply"}))
        assert json.loads(raw.get(topic="test/reply").payload) == {"id": 7, "ok": True, "value": 7}
        raw.publish(TOPICS.call("DistanceRead", "value"),
                    json.dumps({"id": 8, "reply_to": "test/reply", "args": [1]}))
        reply = json.loads(raw.get(topic="test/reply").payload)
        assert reply["ok"] is False and reply["error"]["code"] == "bad_args"


def test_driver_fault_and_latency(mosquitto_broker: BrokerProcess) -> None:
    dep = deployment(DistanceRead={"mock_latency_s": 0.2})
    with running("sonar", dep, mosquitto_broker.url) as host, client(mosquitto_broker.url) as bus:
        with pytest.raises(TimeoutError):
            bus.call("DistanceRead", "value", timeout=0.05)
        sensor: MockDistanceSensor = host.drivers["DistanceRead"]
        assert sensor.wait_until(lambda: sensor.reads == 1, 2.0), "the late read still completes"
        sensor.fail_next("read_distance_cm", "echo pin stuck high")
        with pytest.raises(RemoteError) as caught:
            bus.call("DistanceRead", "value", timeout=2.0)
        assert caught.value.code == "driver_error" and "stuck" in caught.value.message
        assert bus.call("DistanceRead", "value", timeout=2.0) == 100


def test_pigpio_on_the_fake_over_the_bus(mosquitto_broker: BrokerProcess) -> None:
    fake = FakePi(start_tick=(1 << 32) - 3000)
    sonar = fake.attach_hcsr04(trigger=8, echo=7, distance_cm=57.0)
    pigpio_connection.install_fake(fake)
    try:
        dep = deployment(DistanceRead={"samples": 3})
        with running("sonar", dep, mosquitto_broker.url, driver="pigpio"), \
                client(mosquitto_broker.url) as bus:
            assert bus.call("DistanceRead", "value") == 57
            sonar.distance_cm = None
            assert bus.call("DistanceRead", "value") == 400
            assert sonar.pings == 6
    finally:
        pigpio_connection.install_fake(None)


def test_mock_service_process_is_scriptable(mosquitto_broker: BrokerProcess, tmp_path: Path) -> None:
    deploy = tmp_path / "deploy.yaml"
    deploy.write_text(
        "robot: car\n"
        "components:\n"
        "  DistanceRead:\n"
        "    impl: CModelDistanceSensorHCSR\n"
        "    settings: {trigger: 8, echo: 7, mock_distances: [100, 15, null, 60]}\n"
    )
    env = {**os.environ, "UMLBOT_LOG_LEVEL": "WARNING"}
    proc = subprocess.Popen(
        [sys.executable, "-c", "from umlbot.cli import main; main()", "service", "sonar",
         "--deploy", str(deploy), "--driver", "mock", "--broker", mosquitto_broker.url],
        env=env,
    )
    try:
        with client(mosquitto_broker.url) as bus:
            watch = StateWatch(bus, "DistanceRead")
            assert wait_for(lambda: "DistanceRead" in watch.latest, 15.0), "service came online"
            readings = [bus.call("DistanceRead", "value", timeout=5.0) for _ in range(5)]
            assert readings == [100, 15, 400, 60, 60]
    finally:
        proc.terminate()
        # 0: stopped while serving; 130: the SIGTERM came while the start was finishing (the
        # component answers as soon as it is online, a moment before the safety watch starts)
        assert proc.wait(10) in (0, 130)


def test_sim_driver_value_over_the_bus_pings_the_world(mosquitto_broker: BrokerProcess) -> None:
    url = mosquitto_broker.url
    ahead_cm = round((2.0 - CarSpec().sonar_forward_m) * 100)  # the front wall
    with sim_world() as world, running("sonar", deployment("sim"), url), client(url) as bus:
        watch = StateWatch(bus, "DistanceRead")
        assert bus.call("DistanceRead", "value") == ahead_cm
        assert watch.wait("DistanceRead", lambda s: s["echo"]) == {"distance_cm": ahead_cm, "echo": True}
        assert [ping.distance_cm for ping in world.pings] == [ahead_cm], "one ping in the world"
