"""The example plugin package (examples/umlbot_buzzer), installed for real by `make install`, used
from outside exactly like a built-in: `umlbot plugins` lists it without importing a driver, the
compiler checks its kind's features and ranges, `umlbot render` draws it, its drivers pass one
contract suite (mock, lgpio on the fake lgpio, sim), and its service (lgpio driver on the fake
lgpio) serves a compiled model run by `umlbot run` over a real broker."""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from collections.abc import Callable, Iterator
from dataclasses import dataclass
from importlib.metadata import version
from pathlib import Path
from typing import Any

import pytest
from conftest import BrokerProcess, RawClient
from services_support import ROOM, wait_for

from umlbot.base.catalog import implementations_for_service, kind_features, resolve_implementation
from umlbot.base.errors import RemoteError

ROOT = Path(__file__).resolve().parent.parent
EXAMPLE = ROOT / "examples" / "umlbot_buzzer"
MODEL = EXAMPLE / "model"


def umlbot(*args: str, env: dict[str, str] | None = None,
           timeout: float = 60) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-c", "from umlbot.cli import main; main()", *args],
                          capture_output=True, text=True, timeout=timeout, env=env)


def test_the_example_is_installed_as_a_package_of_its_own() -> None:
    assert version("umlbot-buzzer") == "0.1.0", "make install installs examples/umlbot_buzzer"
    impl = resolve_implementation("cmodelbuzzer")
    assert impl is not None and (impl.id, impl.kind, impl.service) == ("passive_buzzer", "sounder", "buzzer")
    assert list(kind_features("sounder")) == ["enabled", "tone"]
    assert [i.id for i in implementations_for_service("buzzer")] == ["passive_buzzer"]


def test_plugins_lists_it_without_importing_drivers() -> None:
    probe = (
        "import sys\nfrom click.testing import CliRunner\nfrom umlbot.cli import cli\n"
        "result = CliRunner().invoke(cli, ['plugins', '--json'])\n"
        "print(result.output)\n"
        "print(sorted(m for m in sys.modules if m.endswith(('.lgpio', '.pigpio', '.mock', '.sim'))))\n"
    )
    done = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, timeout=60)
    listing, _, imported = done.stdout.rpartition("\n[")
    assert imported.strip() == "]", f"listing imported driver modules: [{imported}"
    data = json.loads(listing)
    buzzer = next(p for p in data["packages"] if p["package"] == "umlbot-buzzer")
    assert buzzer == {"package": "umlbot-buzzer", "version": "0.1.0", "kinds": ["sounder"],
                      "services": ["buzzer"], "implementations": ["passive_buzzer (CModelBuzzer)"],
                      "drivers": ["buzzer.lgpio", "buzzer.mock", "buzzer.sim"]}
    assert data["packages"][0]["package"] == "umlbot" and "motor.lgpio" in data["packages"][0]["drivers"]
    assert data["problems"] == []
    text = umlbot("plugins")
    assert text.returncode == 0
    assert "umlbot-buzzer 0.1.0\n  component kinds: sounder\n  service kinds: buzzer" in text.stdout


def test_check_compile_and_render_see_the_plugin(tmp_path: Path) -> None:
    assert umlbot("check", str(MODEL)).returncode == 0
    bad = tmp_path / "bad"
    bad.mkdir()
    (bad / "deployment.yaml").write_text((MODEL / "deployment.yaml").read_text())
    (bad / "model.yaml").write_text((MODEL / "model.yaml").read_text()
                                    .replace("Bell.tone(880)", "Bell.tone(15000)")
                                    .replace("msleep(150)}", "Bell.volume(3)}", 1))
    result = umlbot("check", str(bad))
    assert result.returncode == 1
    assert "argument 1 (hz) of Bell.tone must be 20..10000 by implementation 'passive_buzzer', got 15000" \
        in result.stdout, result.stdout
    assert "unknown feature 'volume' of sounder component 'Bell'" in result.stdout, result.stdout
    compiled = tmp_path / "doorbell.json"
    assert umlbot("compile", str(MODEL), "-o", str(compiled)).returncode == 0
    component = json.loads(compiled.read_text())["components"]["Bell"]
    bound = (component["kind"], component["impl"], component["service"])
    assert bound == ("sounder", "passive_buzzer", "buzzer")
    drawn = umlbot("render", str(MODEL), "-o", str(tmp_path / "diagrams"), "--format", "mermaid")
    assert drawn.returncode == 0, drawn.stderr
    mermaid = "\n".join(p.read_text() for p in (tmp_path / "diagrams").glob("*.mmd"))
    assert "Bell" in mermaid and "sounder" in mermaid


def test_the_compiled_model_carries_its_safe_stop_so_the_orchestrator_needs_no_plugin(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """Compiled where the plugin is installed, run where only umlbot is: the orchestrator still
    silences the Bell at start and end, from the safe stop the compiled file carries."""
    from importlib.metadata import entry_points

    from umlbot.base import plugins
    from umlbot.compiler.api import compile_model
    from umlbot.compiler.compiled import SafeStopCall, dump_compiled, load_compiled
    from umlbot.services.bus import BrokerSettings
    from umlbot.services.orchestrator import Orchestrator

    data = dump_compiled(compile_model(MODEL))
    umlbot_only = plugins.build_catalog(
        *([ep for ep in entry_points(group=group) if ep.dist and ep.dist.metadata["Name"] == "umlbot"]
          for group in (plugins.COMPONENTS_GROUP, plugins.DRIVERS_GROUP)))
    monkeypatch.setattr(plugins, "_catalog", umlbot_only)
    assert resolve_implementation("passive_buzzer") is None, "the plugin is not there"
    compiled = load_compiled(data)
    assert compiled.components["Bell"].safe_stop == [SafeStopCall(feature="enabled", args=[False])]
    orchestrator = Orchestrator(compiled, BrokerSettings.from_url("mqtt://127.0.0.1:1"), handle_signals=False)
    assert orchestrator.actuators == [("Bell", "enabled", (False,))]
    assert "Bell" in orchestrator.required


def test_its_service_runs_a_compiled_model_end_to_end(
    mosquitto_broker: BrokerProcess, raw_client: Callable[..., RawClient], tmp_path: Path
) -> None:
    compiled = tmp_path / "doorbell.json"
    assert umlbot("compile", str(MODEL), "-o", str(compiled)).returncode == 0
    raw = raw_client(mosquitto_broker)
    raw.subscribe("umlbot/doorbell/Bell/state")
    lines = tmp_path / "lines.json"
    env = {**os.environ, "UMLBOT_FAKE_LGPIO": "1", "UMLBOT_FAKE_LGPIO_STATE": str(lines)}
    service = subprocess.Popen(
        [sys.executable, "-c", "from umlbot.cli import main; main()", "service", "buzzer",
         "--deploy", str(MODEL / "deployment.yaml"), "--broker", mosquitto_broker.url],
        env=env, stderr=subprocess.PIPE, text=True,
    )
    try:
        assert wait_for(lambda: lines.exists() and "0:12" in json.loads(lines.read_text())["lines"], 15.0)
        trace = tmp_path / "trace.jsonl"
        run = umlbot("run", str(compiled), "--broker", mosquitto_broker.url, "--trace", str(trace),
                     timeout=60)
        assert run.returncode == 0, run.stderr
        states = []
        while True:
            try:
                states.append(json.loads(raw.get(timeout=1.0).payload))
            except TimeoutError:
                break
        assert {"on": True, "tone_hz": 880} in states and {"on": True, "tone_hz": 660} in states
        assert states[-1]["on"] is False
        events = [json.loads(line) for line in trace.read_text().splitlines()]
        calls = [e["node"] for e in events if e.get("kind") == "action" and e.get("error") is None]
        assert {"high", "ding", "low", "quiet"} <= set(calls), events
    finally:
        service.terminate()
        _, stderr = service.communicate(timeout=10)
    assert service.returncode == 0, stderr
    bell = json.loads(lines.read_text())["lines"]["0:12"]
    assert bell["pwm_frequency"] == 0 and bell["claim"] == "free", "stopping silenced and freed the pin"


def test_its_mock_driver_runs_in_process(mosquitto_broker: BrokerProcess) -> None:
    from services_support import broker_settings, client

    from umlbot.base.deployment import load_deployment
    from umlbot.services.host import ServiceHost

    deployment = load_deployment(MODEL / "deployment.yaml")
    with ServiceHost("buzzer", deployment, broker_settings(mosquitto_broker.url), "car", "mock") as host, \
            client(mosquitto_broker.url) as bus:
        bus.call("Bell", "tone", 523)
        bus.call("Bell", "enabled", True)
        assert host.drivers["Bell"].playing_hz == 523
        with pytest.raises(RemoteError) as caught:
            bus.call("Bell", "tone", 12000)
        assert caught.value.code == "out_of_range"
    assert host.drivers["Bell"].playing_hz is None and host.drivers["Bell"].closed


def test_its_service_is_silenced_when_the_orchestrator_goes_offline(
    mosquitto_broker: BrokerProcess, raw_client: Callable[..., RawClient]
) -> None:
    """The buzzer's ServiceSpec sets `stop_when_orchestrator_offline`, as the built-in motor's
    does: the orchestrator's last will silences it the way it stops a motor."""
    from services_support import broker_settings, client

    from umlbot.base.catalog import service_spec
    from umlbot.base.deployment import load_deployment
    from umlbot.services.bus import Topics
    from umlbot.services.host import ServiceHost

    assert [kind for kind in ("motor", "sonar", "servo", "gpio", "buzzer")
            if getattr(service_spec(kind), "stop_when_orchestrator_offline", None)] == ["motor", "buzzer"]
    raw = raw_client(mosquitto_broker)
    deployment = load_deployment(MODEL / "deployment.yaml")
    with ServiceHost("buzzer", deployment, broker_settings(mosquitto_broker.url), "car", "mock") as host, \
            client(mosquitto_broker.url) as bus:
        bell = host.drivers["Bell"]
        bus.call("Bell", "enabled", True)
        raw.publish(Topics("car").orchestrator_status, json.dumps({"state": "running"}))
        assert not bell.wait_until(lambda: bell.playing_hz is None, 0.3), "running is fine"
        raw.publish(Topics("car").orchestrator_status, json.dumps({"state": "offline"}))
        assert bell.wait_until(lambda: bell.playing_hz is None, 5.0)
        assert host.services["Bell"].state() == {"on": False, "tone_hz": 440}


# --- one driver contract suite over every backend: mock, lgpio on the fake lgpio, sim -------------


@dataclass
class BuzzerRig:
    driver: Any
    playing_hz: Callable[[], int | None]  # None = silent


@pytest.fixture(params=["mock", "lgpio-fake", "sim"])
def buzzer(request: pytest.FixtureRequest) -> Iterator[BuzzerRig]:
    """A buzzer driver as the service gets it, and what it sounds, read from its backend."""
    from umlbot_buzzer.driver import BuzzerSettings
    from umlbot_buzzer.lgpio import LgpioBuzzer

    from umlbot.base.registry import create_driver
    from umlbot.services.simworld import attach_local_world
    from umlbot.sim import World, parse_track
    from umlbot.testing.lgpio import FakeLgpio

    if request.param == "lgpio-fake":
        lg = FakeLgpio()
        driver: Any = LgpioBuzzer("Bell", BuzzerSettings(gpio=12), lg=lg)

        def sounding() -> int | None:
            line = lg.line(12)
            if not line.pwm_frequency:
                return None
            assert line.claim == "output" and line.pwm_duty_percent == 50, "a square wave"
            return int(line.pwm_frequency)

        yield BuzzerRig(driver, sounding)
        driver.close()
        assert lg.line(12).claim == "free", "close frees the pin"
        return
    if request.param == "sim":
        attach_local_world(World(parse_track(ROOM)))
        try:
            driver = create_driver("buzzer", "sim", "Bell", {"gpio": 12})
            yield BuzzerRig(driver, lambda: driver.playing_hz)
            driver.close()
        finally:
            attach_local_world(None)
        return
    driver = create_driver("buzzer", "mock", "Bell", {"gpio": 12})
    yield BuzzerRig(driver, lambda: driver.playing_hz)
    driver.close()


def test_a_buzzer_driver_starts_silent_and_is_a_buzzer(buzzer: BuzzerRig) -> None:
    from umlbot_buzzer.driver import Buzzer

    assert isinstance(buzzer.driver, Buzzer)
    assert buzzer.playing_hz() is None


def test_a_buzzer_driver_plays_the_tone_asked_until_silenced(buzzer: BuzzerRig) -> None:
    buzzer.driver.play(523)
    assert buzzer.playing_hz() == 523
    buzzer.driver.play(10000)
    assert buzzer.playing_hz() == 10000
    buzzer.driver.silence()
    assert buzzer.playing_hz() is None
    buzzer.driver.silence()  # silencing a silent buzzer is no error
    assert buzzer.playing_hz() is None


def test_closing_a_buzzer_driver_silences_it_and_twice_is_safe(buzzer: BuzzerRig) -> None:
    buzzer.driver.play(880)
    buzzer.driver.close()
    assert buzzer.playing_hz() is None
    buzzer.driver.close()
    assert buzzer.playing_hz() is None


def test_umlbot_sim_runs_its_sim_driver_beside_the_car(tmp_path: Path) -> None:
    """The reference car with a Bell added: `umlbot sim` serves it on the plugin's sim driver, the
    orchestrator silences it at start (its safe stop) and the model's calls reach it."""
    car = tmp_path / "car"
    shutil.copytree(ROOT / "models" / "robot_car", car)
    model = car / "model.yaml"
    model.write_text(model.read_text().replace("\nlinks:", "  Bell: {kind: sounder}\n\nlinks:"))
    main = car / "activities" / "main.yaml"
    look = "  - {id: look_ahead, kind: action, call: Sensor.angle(90)}\n"
    assert look in main.read_text()
    calls = ("  - {id: ding, kind: action, call: Bell.tone(523)}\n"
             "  - {id: dong, kind: action, call: Bell.enabled(true)}\n"
             "  - {id: hush, kind: action, call: Bell.enabled(false)}\n")
    main.write_text(main.read_text().replace(look, look + calls))
    deployment = car / "deployment.yaml"
    bell = "  Bell:\n    impl: CModelBuzzer\n    settings: {gpio: 12}\n"
    deployment.write_text(deployment.read_text() + bell)
    result = umlbot("--log-level", "INFO", "--log-json", "sim", str(car), "--track",
                    str(ROOT / "models" / "tracks" / "corridor.yaml"), "--speed", "20",
                    "--plot", str(tmp_path / "run.png"), timeout=120)
    assert result.returncode == 0, result.stderr[-2000:]
    events = [json.loads(line) for line in result.stderr.splitlines() if line.startswith("{")]
    started = [e for e in events if e.get("event") == "service_started" and e.get("kind") == "buzzer"]
    assert started and started[0]["components"] == {"Bell": "sim"}
    assert any(e.get("event") == "actuators_stopped" and "Bell" in e["components"] for e in events)
    assert [e["hz"] for e in events if e.get("event") == "buzzer_on"] == [523]
