"""The gpio service over real brokers: readPin/writePin, refused pins, state, pigpio on the fake."""

from __future__ import annotations

import json
from collections.abc import Callable

import pytest
from conftest import BrokerProcess, RawClient
from services_support import ROBOT, StateWatch, broker_settings, client, deployment, raw_state, running

from umlbot.base.errors import ConfigError, RemoteError
from umlbot.services.bus import Topics
from umlbot.services.gpio.mock import MockGpio
from umlbot.services.host import ServiceHost
from umlbot.services.pins import pigpio as pigpio_connection
from umlbot.testing.pigpio import FakePi

pytestmark = pytest.mark.network
TOPICS = Topics(ROBOT)


def test_read_and_write_pins_via_the_bus(broker: BrokerProcess) -> None:
    dep = deployment(RaspberryPI={"mock_levels": {17: 1}})
    with running("gpio", dep, broker.url) as host, client(broker.url) as bus:
        watch = StateWatch(bus, "RaspberryPI")
        assert bus.call("RaspberryPI", "readPin", 17) == 1
        assert bus.call("RaspberryPI", "writePin", 4, 1) is None
        pins: MockGpio = host.drivers["RaspberryPI"]
        assert pins.levels[4] == 1 and 4 in pins.outputs
        assert bus.call("RaspberryPI", "readPin", 4) == 1
        assert watch.wait("RaspberryPI", lambda s: s["pins"] == {"4": 1, "17": 1})


@pytest.mark.parametrize(("pin", "why"), [(5, "not in the deployment's pins"), (22, "LeftActuator")])
def test_refused_pins_are_out_of_range(mosquitto_broker: BrokerProcess, pin: int, why: str) -> None:
    with running("gpio", deployment(), mosquitto_broker.url) as host, client(mosquitto_broker.url) as bus:
        for feature, args in (("writePin", (pin, 1)), ("readPin", (pin,))):
            with pytest.raises(RemoteError) as caught:
                bus.call("RaspberryPI", feature, *args)
            assert caught.value.code == "out_of_range" and why in caught.value.message
        assert host.drivers["RaspberryPI"].commands == []


def test_default_pins_exclude_every_owned_pin(mosquitto_broker: BrokerProcess) -> None:
    dep = deployment()
    data = json.loads(dep.model_dump_json())
    del data["components"]["RaspberryPI"]["settings"]["pins"]
    from umlbot.base.deployment import Deployment

    with running("gpio", Deployment.model_validate(data), mosquitto_broker.url) as host:
        assert host.drivers["RaspberryPI"].allowed_pins == frozenset(range(28)) - {22, 23, 24, 25, 18, 8, 7}


def test_listing_an_owned_pin_is_a_config_error(mosquitto_broker: BrokerProcess) -> None:
    """Refused before anything connects, in the words of `umlbot check` (one shared-pin rule)."""
    dep = deployment(RaspberryPI={"pins": [4, 8]})
    with pytest.raises(ConfigError, match=r"GPIO 8 \('trigger' of 'DistanceRead'\) is already wired to "
                                          r"'RaspberryPI' \('pins'\)"):
        ServiceHost("gpio", dep, broker_settings(mosquitto_broker.url), ROBOT)


def test_raw_bare_write_and_read(
    mosquitto_broker: BrokerProcess, raw_client: Callable[..., RawClient]
) -> None:
    raw = raw_client(mosquitto_broker)
    raw.subscribe(TOPICS.state("RaspberryPI"))
    with running("gpio", deployment(), mosquitto_broker.url) as host:
        raw.publish(TOPICS.call("RaspberryPI", "writePin"), "[27, 1]")
        assert raw_state(raw, "RaspberryPI", lambda s: s["pins"].get("27") == 1)
        assert host.drivers["RaspberryPI"].levels[27] == 1
        host.drivers["RaspberryPI"].set_level(17, 1)
        raw.publish(TOPICS.call("RaspberryPI", "readPin"), "17")  # bare: the read shows in the state
        assert raw_state(raw, "RaspberryPI", lambda s: s["pins"].get("17") == 1)["pins"]["27"] == 1


def test_pigpio_on_the_fake_over_the_bus(mosquitto_broker: BrokerProcess) -> None:
    fake = FakePi()
    fake.set_input(17, 1)
    pigpio_connection.install_fake(fake)
    try:
        with running("gpio", deployment(), mosquitto_broker.url, driver="pigpio"), \
                client(mosquitto_broker.url) as bus:
            assert bus.call("RaspberryPI", "readPin", 17) == 1
            bus.call("RaspberryPI", "writePin", 4, 1)
            assert fake.pin(4).level == 1 and fake.pin(4).mode == 1
    finally:
        pigpio_connection.install_fake(None)
