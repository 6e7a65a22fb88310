"""Plugin loading: umlbot's own library comes through the same entry points as a plugin's; a broken
plugin (import error, bad spec, name clash, bad driver name) is skipped with a problem naming it,
and the others still load, both in `build_catalog` and for real through an installed package's
metadata in a separate process (`umlbot plugins`, `umlbot check`, `umlbot service`)."""

from __future__ import annotations

import os
import subprocess
import sys
from importlib.metadata import EntryPoint, entry_points
from pathlib import Path

from umlbot.plugins import COMPONENTS_GROUP, DRIVERS_GROUP, build_catalog, catalog

ROOT = Path(__file__).resolve().parent.parent
TESTS = Path(__file__).resolve().parent
BUZZER_MODEL = ROOT / "examples" / "umlbot_buzzer" / "model"

COMPONENTS = {
    "good": "plugin_samples:GOOD",
    "missing": "no_such_plugin_module:PLUGIN",
    "clash": "plugin_samples:CLASH",
    "badspec": "plugin_samples:BAD_SPEC",
    "notaplugin": "plugin_samples:NOT_A_PLUGIN",
}
DRIVERS = {
    "linesensor.mock": "services.sonar.mock:FACTORY",
    "warp.mock": "services.motor.mock:FACTORY",
    "motor.mock": "services.sonar.mock:FACTORY",
    "badname": "services.motor.mock:FACTORY",
    "buzzer.broken": "no_such_driver_module:FACTORY",
}


def test_builtins_come_through_the_entry_points() -> None:
    lib = catalog()
    names = {ep.name: ep.value for ep in entry_points(group=COMPONENTS_GROUP) if ep.dist
             and ep.dist.metadata["Name"] == "umlbot"}
    assert names == {"builtin": "umlbot.library:BUILTIN"}
    assert lib.origin["impl:l298n"] == lib.origin["kind:actuator"] == lib.origin["service:motor"] == "umlbot"
    assert {(k, n) for (k, n), entry in lib.drivers.items() if entry.package == "umlbot"} == {
        (kind, name) for kind in ("motor", "sonar", "servo", "gpio")
        for name in ("pigpio", "lgpio", "mock", *(("sim",) if kind != "gpio" else ()))
    }


def test_a_broken_plugin_is_named_and_the_others_still_load() -> None:
    lib = build_catalog(
        [*entry_points(group=COMPONENTS_GROUP),
         *(EntryPoint(name, value, COMPONENTS_GROUP) for name, value in COMPONENTS.items())],
        [*entry_points(group=DRIVERS_GROUP),
         *(EntryPoint(name, value, DRIVERS_GROUP) for name, value in DRIVERS.items())],
    )
    problems = {p.plugin: p.message for p in lib.problems}
    assert set(problems) == {"missing", "clash", "badspec", "notaplugin", "warp.mock", "motor.mock",
                             "badname"}
    assert problems["missing"].startswith("cannot import no_such_plugin_module:PLUGIN: ModuleNotFoundError")
    taken = "alias 'CModelL298NActuator' is already taken by implementation 'l298n' of umlbot"
    assert taken in problems["clash"]
    assert "may only narrow the kind's maximum 360" in problems["badspec"]
    assert "feature 'value' is not a feature of kind actuator" in problems["badspec"]
    assert problems["notaplugin"] == ("plugin_samples:NOT_A_PLUGIN is a int, "
                                      "not a umlbot.library.ComponentPlugin")
    assert problems["warp.mock"].startswith("unknown service kind 'warp'")
    assert problems["motor.mock"] == "the motor driver 'mock' is already provided by umlbot"
    assert problems["badname"] == "a driver entry point is named '<service kind>.<driver>'"
    # The good plugin is in; nothing of the broken ones is, and the built-ins are untouched.
    assert lib.implementations["tcrt5000"].service == "linesensor"
    assert lib.aliases["cmodellinesensor"] == "tcrt5000"
    assert ("linesensor", "mock") in lib.drivers and ("buzzer", "broken") in lib.drivers
    assert "l298n_clone" not in lib.implementations and "wide_servo" not in lib.implementations
    assert lib.aliases["cmodell298nactuator"] == "l298n"
    assert lib.drivers[("motor", "mock")].package == "umlbot"


def _installed_broken_package(tmp_path: Path) -> dict[str, str]:
    """A package installed in a folder on PYTHONPATH (its dist-info is what pip would write)."""
    info = tmp_path / "broken_plugins-1.0.dist-info"
    info.mkdir()
    (info / "METADATA").write_text("Metadata-Version: 2.1\nName: broken-plugins\nVersion: 1.0\n")
    sections = [f"[{COMPONENTS_GROUP}]", *(f"{k} = {v}" for k, v in COMPONENTS.items()), "",
                f"[{DRIVERS_GROUP}]", *(f"{k} = {v}" for k, v in DRIVERS.items()), ""]
    (info / "entry_points.txt").write_text("\n".join(sections))
    return {**os.environ, "PYTHONPATH": os.pathsep.join([str(tmp_path), str(TESTS)]),
            "UMLBOT_LOG_LEVEL": "WARNING"}


def _umlbot(*args: str, env: dict[str, str]) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-c", "from umlbot.cli import main; main()", *args],
                          capture_output=True, text=True, timeout=60, env=env)


def test_an_installed_broken_package_is_reported_and_does_not_take_down_the_rest(tmp_path: Path) -> None:
    env = _installed_broken_package(tmp_path)
    listing = _umlbot("plugins", env=env)
    assert listing.returncode == 1
    for name in ("missing", "clash", "badspec", "notaplugin", "warp.mock", "motor.mock", "badname"):
        assert f"skipped plugin '{name}' (" in listing.stderr
    assert "package broken-plugins 1.0)" in listing.stderr
    assert "umlbot 0.1.0\n" in listing.stdout and "umlbot-buzzer 0.1.0\n" in listing.stdout
    assert ("broken-plugins 1.0\n  service kinds: linesensor\n"
            "  implementations: tcrt5000 (CModelLineSensor)\n"
            "  drivers: buzzer.broken, linesensor.mock") in listing.stdout

    check = _umlbot("check", str(BUZZER_MODEL), env=env)
    assert check.returncode == 0, check.stdout + check.stderr
    assert "plugin_skipped" in check.stderr and "no_such_plugin_module" in check.stderr
    # a kind the model needs that is missing: the error names the packages whose plugins were skipped
    model = tmp_path / "needs.yaml"
    model.write_text("components:\n  Eye: {kind: warpdrive}\ndeployment:\n  components:\n"
                     "    Eye: {impl: warp9}\nlanes: []\n", encoding="utf-8")
    check = _umlbot("check", str(model), env=env)
    assert check.returncode == 1
    assert ("error: unknown component kind 'warpdrive' (known: system, actuator, sensor, sounder); "
            "skipped plugin packages: broken-plugins (see 'umlbot plugins')") in check.stdout, check.stdout

    line_deploy = tmp_path / "line.yaml"
    line_deploy.write_text("robot: bot\ncomponents:\n  Line: {impl: tcrt5000}\n", encoding="utf-8")
    service = _umlbot("service", "linesensor", "--deploy", str(line_deploy), "--driver", "mock",
                      "--broker", "mqtt://127.0.0.1:1", env=env)
    assert service.returncode == 1
    assert ("error: the linesensor service of package broken-plugins cannot be loaded from "
            "plugin_samples:NoSuchService: AttributeError") in service.stderr, service.stderr
    assert "Traceback" not in service.stderr

    service = _umlbot("service", "buzzer", "--deploy", str(BUZZER_MODEL / "deployment.yaml"), "--driver",
                      "broken", "--broker", "mqtt://127.0.0.1:1", env=env)
    assert service.returncode == 1
    assert ("error: the buzzer driver 'broken' of package broken-plugins cannot be loaded from "
            "no_such_driver_module:FACTORY: ModuleNotFoundError") in service.stderr
