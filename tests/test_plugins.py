"""Plugin loading: umlbot's own library comes through the same entry points as a plugin's; a broken
plugin (import error, bad spec, name clash, bad driver name) is skipped with a problem naming it,
and the others still load, both in `build_catalog` and for real through an installed package's
metadata in a separate process (`umlbot plugins`, `umlbot check`, `umlbot service`)."""

from __future__ import annotations

import os
import subprocess
import sys
import zipfile
from collections.abc import Iterable
from importlib.metadata import EntryPoint, distributions, entry_points
from pathlib import Path
from typing import Any

import pytest

from umlbot.base import entrypoints
from umlbot.base.plugins import COMPONENTS_GROUP, DRIVERS_GROUP, Catalog, build_catalog, catalog

ROOT = Path(__file__).resolve().parent.parent
TESTS = Path(__file__).resolve().parent
BUZZER_MODEL = ROOT / "examples" / "umlbot_buzzer" / "model"

#: broken-plugins 1.0: one mistake per component plugin, and a driver that goes down with them.
BROKEN_COMPONENTS = {
    "missing": "no_such_plugin_module:PLUGIN",
    "clash": "plugin_samples:CLASH",
    "badspec": "plugin_samples:BAD_SPEC",
    "notaplugin": "plugin_samples:NOT_A_PLUGIN",
    "badtypes": "plugin_samples:BAD_TYPES",
    "badstop": "plugin_samples:BAD_STOP",
    "exits": "plugin_sample_exits:PLUGIN",
}
BROKEN_DRIVERS = {"motor.hbboard": "umlbot.services.motor.mock:FACTORY"}
#: good-plugins 1.0: a good component plugin, and one mistake per driver entry point.
GOOD_COMPONENTS = {"good": "plugin_samples:GOOD"}
GOOD_DRIVERS = {
    "linesensor.mock": "umlbot.services.sonar.mock:FACTORY",
    "warp.mock": "umlbot.services.motor.mock:FACTORY",
    "motor.mock": "umlbot.services.sonar.mock:FACTORY",
    "badname": "umlbot.services.motor.mock:FACTORY",
    "buzzer.broken": "no_such_driver_module:FACTORY",
    "buzzer.exits": "plugin_sample_exits:FACTORY",
}
SKIPPED = {*BROKEN_COMPONENTS, *BROKEN_DRIVERS, "warp.mock", "motor.mock", "badname"}


def test_builtins_come_through_the_entry_points() -> None:
    lib = catalog()
    names = {ep.name: ep.value for ep in entry_points(group=COMPONENTS_GROUP) if ep.dist
             and ep.dist.metadata["Name"] == "umlbot"}
    assert names == {"builtin": "umlbot.base.library:BUILTIN", "ros2": "umlbot.services.ros2.library:ROS2"}
    assert lib.origin["impl:l298n"] == lib.origin["kind:actuator"] == lib.origin["service:motor"] == "umlbot"
    assert {(k, n) for (k, n), entry in lib.drivers.items() if entry.package == "umlbot"} == {
        (kind, name) for kind in ("motor", "sonar", "servo", "gpio")
        for name in ("pigpio", "lgpio", "mock", *(("sim",) if kind != "gpio" else ()))
    } | {("stereo", name) for name in ("real", "pigpio", "lgpio", "mock", "sim")} \
      | {("ros2", name) for name in ("dds", "pigpio", "lgpio", "mock", "sim")}


def _write_package(folder: Path, name: str, components: dict[str, str], drivers: dict[str, str]) -> None:
    """An installed package in `folder` (its dist-info is what pip would write)."""
    info = folder / f"{name.replace('-', '_')}-1.0.dist-info"
    info.mkdir(parents=True)
    (info / "METADATA").write_text(f"Metadata-Version: 2.1\nName: {name}\nVersion: 1.0\n")
    sections = [f"[{COMPONENTS_GROUP}]", *(f"{k} = {v}" for k, v in components.items()), "",
                f"[{DRIVERS_GROUP}]", *(f"{k} = {v}" for k, v in drivers.items()), ""]
    (info / "entry_points.txt").write_text("\n".join(sections))


def _installed_broken_packages(tmp_path: Path) -> dict[str, str]:
    """broken-plugins and good-plugins installed in `tmp_path`; the environment that sees them."""
    _write_package(tmp_path, "broken-plugins", BROKEN_COMPONENTS, BROKEN_DRIVERS)
    _write_package(tmp_path, "good-plugins", GOOD_COMPONENTS, GOOD_DRIVERS)
    return {**os.environ, "PYTHONPATH": os.pathsep.join([str(tmp_path), str(TESTS)]),
            "UMLBOT_LOG_LEVEL": "WARNING"}


def _entry_points(folder: Path, group: str) -> list[EntryPoint]:
    return [ep for dist in distributions(path=[str(folder)]) for ep in dist.entry_points if ep.group == group]


def _catalog_with(folder: Path) -> Catalog:
    """The library of the installed packages and those in `folder` (theirs given first)."""
    return build_catalog([*_entry_points(folder, COMPONENTS_GROUP), *entry_points(group=COMPONENTS_GROUP)],
                         [*_entry_points(folder, DRIVERS_GROUP), *entry_points(group=DRIVERS_GROUP)])


def test_a_broken_plugin_is_named_and_the_others_still_load(tmp_path: Path) -> None:
    _installed_broken_packages(tmp_path)
    lib = _catalog_with(tmp_path)
    problems = {p.plugin: p.message for p in lib.problems}
    assert set(problems) == SKIPPED
    assert {p.package for p in lib.problems if p.plugin in BROKEN_COMPONENTS} == {"broken-plugins 1.0"}
    assert problems["missing"].startswith("cannot import no_such_plugin_module:PLUGIN: ModuleNotFoundError")
    taken = "alias 'CModelL298NActuator' is already taken by implementation 'l298n' of umlbot"
    assert taken in problems["clash"]
    assert "may only narrow the kind's maximum 360" in problems["badspec"]
    assert "feature 'value' is not a feature of kind actuator" in problems["badspec"]
    assert problems["notaplugin"] == ("plugin_samples:NOT_A_PLUGIN is a int, "
                                      "not a umlbot.base.library.ComponentPlugin")
    assert problems["warp.mock"].startswith("unknown service kind 'warp'")
    assert problems["motor.mock"] == "the motor driver 'mock' is already provided by umlbot"
    assert problems["badname"] == "a driver entry point is named '<service kind>.<driver>'"
    # The good plugin is in; nothing of the broken ones is, and the built-ins are untouched.
    assert lib.implementations["tcrt5000"].service == "linesensor"
    assert lib.aliases["cmodellinesensor"] == "tcrt5000"
    assert ("linesensor", "mock") in lib.drivers and ("buzzer", "broken") in lib.drivers
    assert "l298n_clone" not in lib.implementations and "wide_servo" not in lib.implementations
    assert "lamp" not in lib.kinds and "bad_stop" not in lib.implementations
    assert lib.aliases["cmodell298nactuator"] == "l298n"
    assert lib.drivers[("motor", "mock")].package == "umlbot"


def test_a_spec_with_wrong_types_is_named_and_skipped(tmp_path: Path) -> None:
    _installed_broken_packages(tmp_path)
    lib = _catalog_with(tmp_path)
    problems = {p.plugin: p.message for p in lib.problems}
    assert problems["badtypes"] == (
        "kind lamp.bright: parameter level: type 'double' is not one of int, float, bool, str; "
        "kind lamp: feature bright returns 'list', not one of int, float, bool, str, none; "
        "service kind 'lampsvc': stop_when_orchestrator_offline must be true or false")
    assert problems["badstop"] == (
        "implementation 'bad_stop': safe_stop enabled('abc'): on must be true or false, got \"abc\"; "
        "implementation 'bad_stop': safe_stop dutycycle(150): percent=150 is outside 0..100 %; "
        "implementation 'bad_stop': safe_stop enabled(): enabled takes 1 argument(s) (on), got 0; "
        "implementation 'bad_stop': safe_stop dutycycle(True): percent must be an integer, got true")


def test_a_plugin_that_exits_at_import_is_named_and_skipped(tmp_path: Path) -> None:
    _installed_broken_packages(tmp_path)
    lib = _catalog_with(tmp_path)
    problems = {p.plugin: p.message for p in lib.problems}
    assert problems["exits"] == "cannot import plugin_sample_exits:PLUGIN: SystemExit: 3"
    assert "tcrt5000" in lib.implementations


def test_the_drivers_of_a_package_whose_component_plugin_was_skipped_are_skipped(tmp_path: Path) -> None:
    _installed_broken_packages(tmp_path)
    lib = _catalog_with(tmp_path)
    problem = next(p for p in lib.problems if p.plugin == "motor.hbboard")
    assert problem.package == "broken-plugins 1.0"
    assert problem.message == ("skipped with this package's component plugins 'badspec', 'badstop', "
                               "'badtypes', 'clash', 'exits', 'missing', 'notaplugin'")
    assert ("motor", "hbboard") not in lib.drivers
    assert ("linesensor", "mock") in lib.drivers  # good-plugins' component plugin loaded


def test_a_second_package_with_the_same_line_does_not_take_the_credit(tmp_path: Path) -> None:
    """The order is umlbot first, then by package name, whatever order the entry points come in
    and even when two packages declare the very same line."""
    _write_package(tmp_path, "zz-copy", {"buzzer": "umlbot_buzzer.spec:PLUGIN"}, {})
    _write_package(tmp_path, "zz-drivers", {}, {"buzzer.mock": "umlbot_buzzer.mock:FACTORY"})
    lib = _catalog_with(tmp_path)
    assert lib.origin["kind:sounder"] == lib.origin["impl:passive_buzzer"] == "umlbot-buzzer"
    assert lib.drivers[("buzzer", "mock")].package == "umlbot-buzzer"
    problems = {p.plugin: (p.package, p.message) for p in lib.problems}
    assert problems["buzzer"][0] == "zz-copy 1.0"
    assert problems["buzzer"][1].startswith("component kind 'sounder' is already defined by umlbot-buzzer; ")
    assert problems["buzzer.mock"] == ("zz-drivers 1.0", "the buzzer driver 'mock' is already provided by "
                                       "umlbot-buzzer")


def _umlbot(*args: str, env: dict[str, str]) -> subprocess.CompletedProcess[str]:
    return subprocess.run([sys.executable, "-c", "from umlbot.cli import main; main()", *args],
                          capture_output=True, text=True, timeout=60, env=env)


def test_an_installed_broken_package_is_reported_and_does_not_take_down_the_rest(tmp_path: Path) -> None:
    env = _installed_broken_packages(tmp_path)
    listing = _umlbot("plugins", env=env)
    assert listing.returncode == 1
    for name in SKIPPED:
        assert f"skipped plugin '{name}' (" in listing.stderr
    assert "package broken-plugins 1.0)" in listing.stderr
    assert "umlbot 0.1.0\n" in listing.stdout and "umlbot-buzzer 0.1.0\n" in listing.stdout
    assert ("good-plugins 1.0\n  service kinds: linesensor\n"
            "  implementations: tcrt5000 (CModelLineSensor)\n"
            "  drivers: buzzer.broken, buzzer.exits, linesensor.mock") in listing.stdout

    check = _umlbot("check", str(BUZZER_MODEL), env=env)
    assert check.returncode == 0, check.stdout + check.stderr
    assert "plugin_skipped" in check.stderr and "no_such_plugin_module" in check.stderr
    # a kind the model needs that is missing: the error names the packages whose plugins were skipped
    model = tmp_path / "needs.yaml"
    model.write_text("components:\n  Eye: {kind: warpdrive}\ndeployment:\n  components:\n"
                     "    Eye: {impl: warp9}\nlanes: []\n", encoding="utf-8")
    check = _umlbot("check", str(model), env=env)
    assert check.returncode == 1
    assert ("error: unknown component kind 'warpdrive' "
            "(known: system, actuator, sensor, camera, ros2, sounder); "
            "skipped plugin packages: broken-plugins (see 'umlbot plugins')") in check.stdout, check.stdout

    line_deploy = tmp_path / "line.yaml"
    line_deploy.write_text("robot: bot\ncomponents:\n  Line: {impl: tcrt5000}\n", encoding="utf-8")
    service = _umlbot("service", "linesensor", "--deploy", str(line_deploy), "--driver", "mock",
                      "--broker", "mqtt://127.0.0.1:1", env=env)
    assert service.returncode == 1
    assert ("error: the linesensor service of package good-plugins cannot be loaded from "
            "plugin_samples:NoSuchService: AttributeError") in service.stderr, service.stderr
    assert "Traceback" not in service.stderr

    service = _umlbot("service", "buzzer", "--deploy", str(BUZZER_MODEL / "deployment.yaml"), "--driver",
                      "broken", "--broker", "mqtt://127.0.0.1:1", env=env)
    assert service.returncode == 1
    assert ("error: the buzzer driver 'broken' of package good-plugins cannot be loaded from "
            "no_such_driver_module:FACTORY: ModuleNotFoundError") in service.stderr
    service = _umlbot("service", "buzzer", "--deploy", str(BUZZER_MODEL / "deployment.yaml"), "--driver",
                      "exits", "--broker", "mqtt://127.0.0.1:1", env=env)
    assert service.returncode == 1, service.stderr  # not the module's own exit status 3
    assert ("error: the buzzer driver 'exits' of package good-plugins cannot be loaded from "
            "plugin_sample_exits:FACTORY: SystemExit: 3") in service.stderr


def _described(eps: Iterable[Any]) -> list[tuple[str, str, str, str | None, str | None]]:
    return [(ep.name, ep.value, ep.group, ep.dist.metadata["Name"], ep.dist.version) for ep in eps]


def test_the_light_reader_finds_what_importlib_metadata_finds(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """umlbot.base.entrypoints reads the same entry points as importlib.metadata, in the same order:
    the installed ones, a package on sys.path, and of two with one name the first on sys.path."""
    first, second = tmp_path / "first", tmp_path / "second"
    _write_package(first, "good-plugins", GOOD_COMPONENTS, GOOD_DRIVERS)
    _write_package(second, "Good.Plugins", {"shadowed": "plugin_samples:GOOD"}, {})  # same name, later
    monkeypatch.setattr(sys, "path", [str(first), str(second), *sys.path])
    assert entrypoints._distributions() is not None, "this layout is read without importlib.metadata"
    for group in (COMPONENTS_GROUP, DRIVERS_GROUP, "console_scripts", "pydantic"):
        light = _described(entrypoints.entry_points(group))
        assert light == _described(entry_points(group=group)), group
    assert ("good", "plugin_samples:GOOD", COMPONENTS_GROUP, "good-plugins", "1.0") in _described(
        entrypoints.entry_points(COMPONENTS_GROUP))
    assert "shadowed" not in {ep.name for ep in entrypoints.entry_points(COMPONENTS_GROUP)}
    loaded = next(ep for ep in entrypoints.entry_points(DRIVERS_GROUP) if ep.name == "warp.mock").load()
    assert loaded is next(ep for ep in entry_points(group=DRIVERS_GROUP) if ep.name == "warp.mock").load()


def test_a_zip_on_sys_path_goes_to_importlib_metadata(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A layout the light reader does not read itself (a zip archive) is read by importlib.metadata."""
    archive = tmp_path / "plugins.zip"
    with zipfile.ZipFile(archive, "w") as zipped:
        zipped.writestr("zipped_plugin-1.0.dist-info/METADATA", "Name: zipped-plugin\nVersion: 1.0\n")
        zipped.writestr("zipped_plugin-1.0.dist-info/entry_points.txt",
                        f"[{COMPONENTS_GROUP}]\nzipped = plugin_samples:GOOD\n")
    monkeypatch.setattr(sys, "path", [str(archive), *sys.path])
    assert entrypoints._distributions() is None
    found = _described(entrypoints.entry_points(COMPONENTS_GROUP))
    assert ("zipped", "plugin_samples:GOOD", COMPONENTS_GROUP, "zipped-plugin", "1.0") in found
    assert found == _described(entry_points(group=COMPONENTS_GROUP))
