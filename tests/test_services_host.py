"""The service host and `umlbot service`: driver choice, clear start-up errors, clean stops,
runtime driver registration (how the simulator plugs in), and the registry's settings rules."""

from __future__ import annotations

import os
import subprocess
import sys
import threading
import time
from pathlib import Path
from typing import Any

import pytest
from conftest import BrokerProcess, free_port
from services_support import ROBOT, broker_settings, client, deployment, running

from umlbot.base import registry
from umlbot.base.catalog import service_kinds
from umlbot.base.deployment import owned_pins, parse_deployment
from umlbot.base.errors import ConfigError, DriverError, NotConnected, UnknownDriver
from umlbot.services.host import ServiceGroup, ServiceHost
from umlbot.services.motor import L298NSettings
from umlbot.services.motor.mock import MockMotorChannel, MockMotorSettings


def test_unknown_driver_lists_the_known_names() -> None:
    known = r"unknown motor driver 'warp'; known drivers: auto, lgpio, mock, pigpio"
    with pytest.raises(UnknownDriver, match=known):
        registry.get_factory("motor", "warp")


def test_unknown_kind() -> None:
    with pytest.raises(ConfigError, match="unknown service kind"):
        ServiceHost("lidar", deployment(), broker_settings("mqtt://127.0.0.1:1"), ROBOT)


def test_deployment_without_components_of_the_kind() -> None:
    dep = parse_deployment("LeftActuator=CModelL298NActuator\n")
    with pytest.raises(ConfigError, match="no component served by the sonar service"):
        ServiceHost("sonar", dep, broker_settings("mqtt://127.0.0.1:1"), ROBOT)


def test_settings_prefixes_are_stripped_per_driver() -> None:
    raw = {"in1": 22, "in2": 23, "mock_latency_s": 0.1, "sim_mass_kg": 1.2}
    assert registry.driver_settings("pigpio", raw) == {"in1": 22, "in2": 23}
    assert registry.driver_settings("mock", raw) == {"in1": 22, "in2": 23, "mock_latency_s": 0.1}
    assert registry.driver_settings("sim", raw) == {"in1": 22, "in2": 23, "sim_mass_kg": 1.2}


def test_a_typo_in_a_pigpio_setting_is_a_config_error() -> None:
    with pytest.raises(ConfigError, match=r"LeftActuator: invalid settings: .*in_1: Extra inputs"):
        registry.create_driver("motor", "pigpio", "LeftActuator", {"in_1": 22, "in2": 23})


@pytest.mark.parametrize("driver", ["mock", "sim"])
def test_the_mock_and_sim_drivers_refuse_what_the_hardware_drivers_refuse(driver: str) -> None:
    """A misspelt key or a pin out of range is refused as pigpio refuses it (so what runs under
    mock is not refused on the robot); only a missing pin is forgiven (they need no pins)."""
    typo = {"in_1": 22, "in2": 23}
    with pytest.raises(ConfigError) as hardware:
        registry.create_driver("motor", "pigpio", "LeftActuator", typo)
    with pytest.raises(ConfigError) as mock:
        registry.create_driver("motor", driver, "LeftActuator", typo)
    assert str(mock.value) == "LeftActuator: invalid settings: in_1: Extra inputs are not permitted"
    assert "in_1: Extra inputs are not permitted" in str(hardware.value)
    with pytest.raises(ConfigError, match=r"^Sensor: invalid settings: gpio: Input should be less than or "
                                          r"equal to 27$"):
        registry.create_driver("servo", "mock", "Sensor", {"gpio": 28})
    assert registry.settings_problems("motor", driver, typo) == [(("in_1",), "Extra inputs are not "
                                                                             "permitted")]
    assert registry.settings_problems("motor", driver, {}) == []  # no pins: fine without hardware
    channel = registry.create_driver("motor", "mock", "LeftActuator", {"mock_latency_s": 0})
    channel.close()


def test_a_misspelt_setting_under_mock_is_refused_at_its_position() -> None:
    dep = parse_deployment("driver: mock\ncomponents:\n  LeftActuator:\n    impl: l298n\n"
                           "    settings: {in1: 22, in_2: 23}\n", "deployment.yaml")
    host = ServiceHost("motor", dep, broker_settings("mqtt://127.0.0.1:1"), ROBOT)
    with pytest.raises(ConfigError, match=r"^deployment\.yaml:5:25: component LeftActuator: settings\.in_2: "
                                          r"Extra inputs are not permitted$"):
        host.start()


def test_owned_pins_of_the_reference_robot() -> None:
    # the gpio component's `pins` list counts as its own, as every single-pin setting does
    assert owned_pins(deployment()) == {4: "RaspberryPI", 17: "RaspberryPI", 27: "RaspberryPI",
                                        22: "LeftActuator", 23: "LeftActuator", 24: "RightActuator",
                                        25: "RightActuator", 18: "Sensor", 8: "DistanceRead",
                                        7: "DistanceRead"}


def test_runtime_registered_driver_is_used(mosquitto_broker: BrokerProcess) -> None:
    made: list[MockMotorChannel] = []

    def create(component: str, settings: L298NSettings) -> MockMotorChannel:
        made.append(MockMotorChannel(component, MockMotorSettings(watchdog_s=settings.watchdog_s)))
        return made[-1]

    registry.register_driver("motor", "bench", registry.DriverFactory(L298NSettings, create))
    try:
        assert "bench" in registry.known_drivers("motor")
        with running("motor", deployment(), mosquitto_broker.url, driver="bench") as host, \
                client(mosquitto_broker.url) as bus:
            bus.call("LeftActuator", "enabled", True)
            assert [d.component for d in made] == ["LeftActuator", "RightActuator"]
            assert host.drivers["LeftActuator"] is made[0] and made[0].enabled
    finally:
        registry.unregister_driver("motor", "bench")
    assert "bench" not in registry.known_drivers("motor")


def test_per_component_driver_override(mosquitto_broker: BrokerProcess) -> None:
    dep = parse_deployment(
        "driver: pigpio\n"
        "components:\n"
        "  LeftActuator: {impl: l298n, driver: mock}\n"
    )
    with running("motor", dep, mosquitto_broker.url) as host:
        assert host.driver_name("LeftActuator") == "mock"
        assert isinstance(host.drivers["LeftActuator"], MockMotorChannel)


def test_failed_start_releases_what_was_built(monkeypatch: pytest.MonkeyPatch) -> None:
    built: list[Any] = []
    original = registry.create_driver

    def create(kind: Any, driver: str, component: str, settings: Any) -> Any:
        if component == "RightActuator":
            raise DriverError("cannot reach the pigpio daemon")
        built.append(original(kind, driver, component, settings))
        return built[-1]

    monkeypatch.setattr("umlbot.services.host.create_driver", create)
    host = ServiceHost("motor", deployment(), broker_settings("mqtt://127.0.0.1:1"), ROBOT)
    with pytest.raises(DriverError):
        host.start()
    assert len(built) == 1 and built[0].closed


def test_unreachable_broker_is_not_connected_and_motors_stay_stopped() -> None:
    host = ServiceHost("motor", deployment(), broker_settings(f"mqtt://127.0.0.1:{free_port()}"), ROBOT,
                       connect_timeout_s=0.5)
    with pytest.raises(NotConnected):
        host.start()
    left: MockMotorChannel = host.drivers["LeftActuator"]
    assert left.closed and not left.running
    host.stop()  # twice is fine


def test_stop_is_idempotent_and_start_after_stop_is_harmless(mosquitto_broker: BrokerProcess) -> None:
    host = ServiceHost("servo", deployment(), broker_settings(mosquitto_broker.url), ROBOT)
    host.start()
    host.start()
    host.stop()
    host.stop()
    assert host.drivers["Sensor"].closed


def test_a_signal_inside_a_thread_start_stops_cleanly(mosquitto_broker: BrokerProcess,
                                                       monkeypatch: pytest.MonkeyPatch) -> None:
    # SIGTERM while `umlbot service` starts raises KeyboardInterrupt wherever the main thread is,
    # also inside Thread.start() of the safety ticker: the stop that follows must not trip over
    # the thread that never started (it once raised "cannot join thread before it is started").
    original = threading.Thread.start

    def start(thread: threading.Thread) -> None:
        if thread.name.endswith("-safety"):
            raise KeyboardInterrupt
        original(thread)

    monkeypatch.setattr(threading.Thread, "start", start)
    host = ServiceHost("motor", deployment(), broker_settings(mosquitto_broker.url), ROBOT)
    with pytest.raises(KeyboardInterrupt):
        host.start()
    left: MockMotorChannel = host.drivers["LeftActuator"]
    assert left.closed and not left.running
    host.stop()  # twice is fine


def _cli(
    *args: str, env: dict[str, str] | None = None, timeout: float = 30
) -> subprocess.CompletedProcess[str]:
    return subprocess.run(
        [sys.executable, "-c", "from umlbot.cli import main; main()", *args],
        capture_output=True, text=True, timeout=timeout, env={**os.environ, **(env or {})},
    )


def test_service_started_names_the_drivers_that_run(mosquitto_broker: BrokerProcess, tmp_path: Path) -> None:
    """`driver: auto` is logged as what it chose (here the fake lgpio), not as "auto"."""
    import json
    import queue
    import threading

    deploy = tmp_path / "d.yaml"
    deploy.write_text("driver: auto\ncomponents:\n  Sensor: {impl: servo, settings: {gpio: 18}}\n"
                      "  Tilt: {impl: servo, driver: mock, settings: {gpio: 19}}\n")
    env = {**os.environ, "UMLBOT_FAKE_LGPIO": "1"}
    env.pop("UMLBOT_FAKE_PIGPIO", None)
    proc = subprocess.Popen(
        [sys.executable, "-c", "from umlbot.cli import main; main()", "--log-level", "INFO", "--log-json",
         "service", "servo", "--deploy", str(deploy), "--robot", "autocar", "--broker", mosquitto_broker.url],
        stderr=subprocess.PIPE, stdout=subprocess.DEVNULL, text=True, env=env)
    lines: queue.Queue[str] = queue.Queue()
    assert proc.stderr is not None
    stderr = proc.stderr
    def read() -> None:
        for line in stderr:
            lines.put(line)

    threading.Thread(target=read, daemon=True).start()
    try:
        deadline = time.monotonic() + 30
        started = None
        while started is None and time.monotonic() < deadline:
            try:
                line = lines.get(timeout=max(0.0, deadline - time.monotonic()))
            except queue.Empty:
                break
            if line.startswith("{") and json.loads(line).get("event") == "service_started":
                started = json.loads(line)
        assert started is not None, "no service_started line within 30 s"
        assert started["components"] == {"Sensor": "lgpio", "Tilt": "mock"}
    finally:
        proc.terminate()
        # 130: the signal came in the instant between the line and the command's "running" mark
        assert proc.wait(10) in (0, 130)


def test_cli_unknown_driver_is_one_clear_line(tmp_path: Path) -> None:
    deploy = tmp_path / "d.txt"
    deploy.write_text("LeftActuator=CModelL298NActuator\n")
    result = _cli("service", "motor", "--deploy", str(deploy), "--driver", "warp",
                  "--broker", f"mqtt://127.0.0.1:{free_port()}")
    assert result.returncode == 1
    assert "unknown motor driver 'warp'; known drivers: auto, lgpio, mock, pigpio" in result.stderr


def test_cli_pigpio_without_daemon_says_how_to_start_it(tmp_path: Path) -> None:
    deploy = tmp_path / "d.yaml"
    deploy.write_text("driver: pigpio\n"
                      "components:\n  LeftActuator: {impl: l298n, settings: {in1: 22, in2: 23}}\n")
    result = _cli("service", "motor", "--deploy", str(deploy), "--broker", f"mqtt://127.0.0.1:{free_port()}",
                  env={"PIGPIO_PORT": str(free_port())})
    assert result.returncode == 1
    assert "pigpio" in result.stderr and ("pip install" in result.stderr or "pigpiod" in result.stderr)


def test_cli_auto_on_a_machine_without_gpio_says_what_it_looked_for(tmp_path: Path) -> None:
    """The default driver is `auto`; here (no Pi 5, no pigpiod, no gpiochip) it names all three."""
    deploy = tmp_path / "d.yaml"
    deploy.write_text("components:\n  LeftActuator: {impl: l298n, settings: {in1: 22, in2: 23}}\n")
    port = free_port()
    result = _cli("service", "motor", "--deploy", str(deploy), "--broker", f"mqtt://127.0.0.1:{free_port()}",
                  env={"PIGPIO_PORT": str(port)})
    assert result.returncode == 1
    if Path("/dev/gpiochip0").exists() or Path("/proc/device-tree/model").exists():
        assert "gpiochip" in result.stderr  # a board with GPIO: lgpio was chosen and says why it failed
    else:
        assert (f"error: driver auto found no GPIO backend: not a Raspberry Pi 5, no pigpio daemon at "
                f"localhost:{port} and no /dev/gpiochip*; on a machine without GPIO use --driver mock or sim"
                in result.stderr)


def test_cli_missing_deployment(tmp_path: Path) -> None:
    result = _cli("service", "gpio", "--deploy", str(tmp_path / "nope.yaml"))
    assert result.returncode == 1 and "cannot read deployment" in result.stderr


def test_cli_robot_from_env_and_plain_deployment(mosquitto_broker: BrokerProcess, tmp_path: Path) -> None:
    deploy = tmp_path / "d.txt"
    deploy.write_text("Sensor=CModelActuator\n")
    proc = subprocess.Popen(
        [sys.executable, "-c", "from umlbot.cli import main; main()", "service", "servo",
         "--deploy", str(deploy), "--driver", "mock", "--broker", mosquitto_broker.url],
        env={**os.environ, "UMLBOT_ROBOT": ROBOT, "UMLBOT_LOG_LEVEL": "WARNING"},
    )
    try:
        with client(mosquitto_broker.url) as bus:
            deadline = time.monotonic() + 15
            while True:
                try:
                    assert bus.call("Sensor", "angle", 10, timeout=0.5) is None
                    break
                except TimeoutError:
                    assert time.monotonic() < deadline, "service never answered"
    finally:
        proc.terminate()
        assert proc.wait(10) == 0


def test_service_all_serves_every_kind_in_one_process(
    mosquitto_broker: BrokerProcess, tmp_path: Path
) -> None:
    """`umlbot service all`: every component of the car answers; SIGTERM stops it cleanly."""
    deploy = tmp_path / "car.txt"
    deploy.write_text("LeftActuator=l298n\nRightActuator=l298n\nDistanceRead=hcsr04\nSensor=servo\n"
                      "RaspberryPI=raspberrypi\n", encoding="utf-8")
    proc = subprocess.Popen(
        [sys.executable, "-c", "from umlbot.cli import main; main()", "service", "all",
         "--deploy", str(deploy), "--driver", "mock", "--broker", mosquitto_broker.url, "--robot", ROBOT],
        env={**os.environ, "UMLBOT_LOG_LEVEL": "WARNING"},
    )
    try:
        with client(mosquitto_broker.url) as bus:
            deadline = time.monotonic() + 20
            while True:  # the process is serving once its last component answers
                try:
                    assert bus.call("RaspberryPI", "readPin", 5, timeout=0.5) in (0, 1)
                    break
                except TimeoutError:
                    assert proc.poll() is None and time.monotonic() < deadline, "service all never answered"
            assert bus.call("LeftActuator", "dutycycle", 40) is None
            assert bus.call("RightActuator", "enabled", True) is None
            assert isinstance(bus.call("DistanceRead", "value"), int)
            assert bus.call("Sensor", "angle", 90) is None
    finally:
        proc.terminate()
        assert proc.wait(10) == 0


def test_service_group_stops_motors_first_and_checks_components(mosquitto_broker: BrokerProcess) -> None:
    group = ServiceGroup(service_kinds(), deployment(), broker_settings(mosquitto_broker.url), ROBOT,
                         components=["LeftActuator", "DistanceRead"])
    assert [host.kind for host in group.hosts] == ["motor", "sonar"]
    with group:
        assert sorted(group.components) == ["DistanceRead", "LeftActuator"]
        with client(mosquitto_broker.url) as bus:
            bus.call("LeftActuator", "dutycycle", 50)
            bus.call("LeftActuator", "enabled", True)
        assert group.hosts[0].drivers["LeftActuator"].running
    assert not group.hosts[0].drivers["LeftActuator"].running
    with pytest.raises(ConfigError, match=r"no component\(s\) \['Wheel'\] in the deployment"):
        ServiceGroup(service_kinds(), deployment(), broker_settings(mosquitto_broker.url), ROBOT,
                     components=["Wheel"])


def _statuses(url: str, *components: str) -> dict[str, dict[str, Any]]:
    """The retained status of each component, read by a fresh raw subscription."""
    import json

    import paho.mqtt.subscribe as subscribe

    from umlbot.services.bus import Topics

    port = int(url.rsplit(":", 1)[1])
    topics = [Topics(ROBOT).status(c) for c in components]
    msgs = subscribe.simple(  # type: ignore[no-untyped-call]
        topics, hostname="127.0.0.1", port=port, msg_count=len(topics), retained=True)
    found = msgs if isinstance(msgs, list) else [msgs]
    return {m.topic.split("/")[-2]: json.loads(m.payload) for m in found}


def test_the_status_says_the_driver_that_runs_with_auto_resolved(
    mosquitto_broker: BrokerProcess, monkeypatch: pytest.MonkeyPatch
) -> None:
    """`--driver mock` over a deployment that says `auto` says "mock"; `auto` alone says what it
    chose on this machine (here the fake pigpio the environment asks for), never "auto"."""
    from umlbot.base import autodetect

    with running("motor", deployment("auto"), mosquitto_broker.url, "mock"):
        status = _statuses(mosquitto_broker.url, "LeftActuator", "RightActuator")
        assert {s["driver"] for s in status.values()} == {"mock"}
    assert "driver" not in _statuses(mosquitto_broker.url, "LeftActuator")["LeftActuator"]  # offline
    monkeypatch.setenv("UMLBOT_FAKE_PIGPIO", "1")
    autodetect.forget()
    try:
        with running("motor", deployment("auto"), mosquitto_broker.url) as host:
            assert host.chosen_drivers["LeftActuator"] == "pigpio"
            assert _statuses(mosquitto_broker.url, "LeftActuator")["LeftActuator"]["driver"] == "pigpio"
    finally:
        autodetect.forget()


@pytest.mark.parametrize("kind", ["amqtt", "mosquitto"])
def test_a_second_service_for_a_served_component_refuses_and_leaves_the_first_online(
    kind: str, request: pytest.FixtureRequest
) -> None:
    from umlbot.services.bus.server import ComponentTaken

    broker: BrokerProcess = request.getfixturevalue(f"{kind}_broker")
    with running("motor", deployment(), broker.url) as first:
        mine = {name: server.instance for name, server in first.servers.items()}
        second = ServiceHost("motor", deployment(), broker_settings(broker.url), ROBOT, "mock")
        with pytest.raises(ComponentTaken, match=r"already served by the running instance [0-9a-f]{16} "):
            second.start()
        # the refused one stopped itself without saying offline for the components it never served
        status = _statuses(broker.url, "LeftActuator", "RightActuator")
        assert {name: s["instance"] for name, s in status.items()} == mine
        assert not any("client_id" in s for s in status.values())  # never published
        assert all(s["state"] == "online" for s in status.values())
        with client(broker.url) as bus:
            bus.call("LeftActuator", "dutycycle", 40)
        assert first.drivers["LeftActuator"].duty_cycle_percent == 40
    # the first one's own stop still says offline
    after = _statuses(broker.url, "LeftActuator", "RightActuator")
    assert {s["state"] for s in after.values()} == {"offline"}


def test_a_stale_online_status_is_replaced(mosquitto_broker: BrokerProcess) -> None:
    """A retained `online` whose client does not answer (a broker that kept it over a restart)
    does not block the start."""
    import paho.mqtt.publish as publish

    from umlbot.services.bus import Topics

    publish.single(Topics(ROBOT).status("LeftActuator"), '{"state": "online", "instance": "ghost"}',
                   retain=True, hostname="127.0.0.1", port=mosquitto_broker.port)
    started = time.monotonic()
    with running("motor", deployment(), mosquitto_broker.url) as host:
        assert time.monotonic() - started < 4.0
        status = _statuses(mosquitto_broker.url, "LeftActuator")["LeftActuator"]
        assert status["instance"] == host.servers["LeftActuator"].instance
