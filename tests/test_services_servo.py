"""The servo service over real brokers: angle via the bus and raw payloads, range errors, state,
pulses off on stop, pigpio on the fake, and the sim driver turning a simulated world's servo."""

from __future__ import annotations

import json
from collections.abc import Callable

import pytest
from conftest import BrokerProcess, RawClient
from services_support import ROBOT, StateWatch, client, deployment, raw_state, running, sim_world

from umlbot.base.errors import RemoteError
from umlbot.services.bus import Topics
from umlbot.services.pins import pigpio as pigpio_connection
from umlbot.services.servo.mock import MockServo
from umlbot.testing.pigpio import FakePi

pytestmark = pytest.mark.network
TOPICS = Topics(ROBOT)


def test_angle_via_the_bus_and_state(broker: BrokerProcess) -> None:
    with running("servo", deployment(), broker.url) as host, client(broker.url) as bus:
        watch = StateWatch(bus, "Sensor")
        assert watch.wait("Sensor", lambda s: True) == {"angle": None}
        assert bus.call("Sensor", "angle", 45) is None
        assert watch.wait("Sensor", lambda s: s["angle"] == 45)
        servo: MockServo = host.drivers["Sensor"]
        assert servo.angle_deg == 45 and servo.pulsing
    assert (servo.pulsing, servo.closed) == (False, True), "stopping the service stops the pulses"


def test_a_safe_stop_makes_the_servo_limp_and_says_so(mosquitto_broker: BrokerProcess) -> None:
    """As docs/services.md says: a lost broker connection and the service stopping switch the
    pulses off and the retained state becomes {"angle": null}; the next angle drives it again."""
    with running("servo", deployment(), mosquitto_broker.url) as host:
        servo: MockServo = host.drivers["Sensor"]
        with client(mosquitto_broker.url) as bus:
            bus.call("Sensor", "angle", 45)
            assert servo.pulsing
        mosquitto_broker.restart()  # no persistence: the retained state is gone with it
        assert servo.wait_until(lambda: not servo.pulsing, timeout=10), "limp on a lost connection"
        with client(mosquitto_broker.url) as bus:
            watch = StateWatch(bus, "Sensor")
            assert watch.wait("Sensor", lambda s: True, timeout=15) == {"angle": None}  # republished
            assert bus.call("Sensor", "angle", 60, timeout=5.0) is None
            assert servo.angle_deg == 60 and servo.pulsing
            watch.wait("Sensor", lambda s: s["angle"] == 60)
    with client(mosquitto_broker.url) as bus:
        watch = StateWatch(bus, "Sensor")
        assert watch.wait("Sensor", lambda s: True) == {"angle": None}, "the stop left the old angle"
    assert (servo.pulsing, servo.closed) == (False, True)


def test_the_initial_angle_is_the_first_state(mosquitto_broker: BrokerProcess) -> None:
    with running("servo", deployment(Sensor={"initial_angle_deg": 90}), mosquitto_broker.url) as host, \
            client(mosquitto_broker.url) as bus:
        assert StateWatch(bus, "Sensor").wait("Sensor", lambda s: True) == {"angle": 90}
        assert host.drivers["Sensor"].pulsing


@pytest.mark.parametrize("degrees", [181, 360, -5])
def test_angle_outside_the_implementation_range_is_out_of_range(
    mosquitto_broker: BrokerProcess, degrees: int
) -> None:
    with running("servo", deployment(), mosquitto_broker.url) as host, client(mosquitto_broker.url) as bus:
        with pytest.raises(RemoteError) as caught:
            bus.call("Sensor", "angle", degrees)
        assert caught.value.code == "out_of_range"
        assert host.drivers["Sensor"].commands == []


def test_narrower_servo_range_from_settings(mosquitto_broker: BrokerProcess) -> None:
    dep = deployment(Sensor={"max_angle_deg": 90})
    with running("servo", dep, mosquitto_broker.url), client(mosquitto_broker.url) as bus:
        bus.call("Sensor", "angle", 90)
        with pytest.raises(RemoteError) as caught:
            bus.call("Sensor", "angle", 120)
        assert caught.value.code == "out_of_range" and "0..90" in caught.value.message


def test_raw_bare_angle(mosquitto_broker: BrokerProcess, raw_client: Callable[..., RawClient]) -> None:
    raw = raw_client(mosquitto_broker)
    raw.subscribe(TOPICS.state("Sensor"))
    with running("servo", deployment(), mosquitto_broker.url) as host:
        raw.publish(TOPICS.call("Sensor", "angle"), "135")
        assert raw_state(raw, "Sensor", lambda s: s["angle"] == 135)
        assert host.drivers["Sensor"].angle_deg == 135
        raw.subscribe("test/reply")
        raw.publish(TOPICS.call("Sensor", "angle"), json.dumps({"id": "a", "reply_to": "test/reply",
                                                                "args": [90.5]}))
        assert json.loads(raw.get(topic="test/reply").payload)["error"]["code"] == "bad_args"


def test_pigpio_on_the_fake_over_the_bus(mosquitto_broker: BrokerProcess) -> None:
    fake = FakePi()
    pigpio_connection.install_fake(fake)
    try:
        dep = deployment(Sensor={"min_pulse_us": 600, "max_pulse_us": 2400})
        with running("servo", dep, mosquitto_broker.url, driver="pigpio"), \
                client(mosquitto_broker.url) as bus:
            bus.call("Sensor", "angle", 90)
            assert fake.pin(18).servo_pulsewidth == 1500
            bus.call("Sensor", "angle", 0)
            assert fake.pin(18).servo_pulsewidth == 600
        assert fake.pin(18).servo_pulsewidth == 0, "pulses off on stop"
    finally:
        pigpio_connection.install_fake(None)


def test_sim_driver_angle_over_the_bus_turns_the_world_servo(mosquitto_broker: BrokerProcess) -> None:
    url = mosquitto_broker.url
    with sim_world() as world, running("servo", deployment("sim"), url), client(url) as bus:
        assert world.servo_angle_deg() == 90
        assert bus.call("Sensor", "angle", 180) is None
        world.advance_to(1.0)  # the servo turns at 600°/s
        assert world.servo_angle_deg() == 180
        with pytest.raises(RemoteError) as caught:
            bus.call("Sensor", "angle", 200)
        assert caught.value.code == "out_of_range"
        world.advance_to(2.0)
        assert world.servo_angle_deg() == 180, "a refused angle does not move the servo"
