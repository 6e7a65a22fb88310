"""Bad input on every `umlbot` command, run as a user runs it: the console script in a subprocess.

Each case expects its documented exit status (docs/cli.md), exactly one message line on stderr
that says what is wrong and where (structured log lines and click's usage preamble aside), no
traceback, no password, and an end within CASE_TIMEOUT_S. The table runs four cases at a time
(they are independent processes) so that the whole file stays well under a minute.
"""

from __future__ import annotations

import json
import os
import re
import signal
import subprocess
import sys
import threading
import time
from collections.abc import Iterator
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from pathlib import Path

import pytest
from conftest import BrokerProcess, _broker, free_port

from umlbot.base.deployment import load_deployment
from umlbot.services.bus import BrokerSettings
from umlbot.services.host import ServiceHost

pytestmark = pytest.mark.network

UMLBOT = str(Path(sys.executable).with_name("umlbot"))
REPO = Path(__file__).resolve().parents[1]
MODEL = str(REPO / "models" / "robot_car")
DEPLOYMENT = str(REPO / "models" / "robot_car" / "deployment.yaml")
TRACK = str(REPO / "models" / "tracks" / "corridor.yaml")
CASE_TIMEOUT_S = 15.0
PASSWORD = "hunter2"


@dataclass(frozen=True)
class Outcome:
    code: int
    stdout: str
    stderr: str
    seconds: float


def user_env(**extra: str) -> dict[str, str]:
    """The environment of a user who set nothing for umlbot."""
    env = {k: v for k, v in os.environ.items() if not k.startswith("UMLBOT_")}
    return {**env, **extra}


def run_umlbot(args: list[str], cwd: Path, env: dict[str, str] | None = None) -> Outcome:
    started = time.monotonic()
    try:
        done = subprocess.run([UMLBOT, *args], capture_output=True, text=True, cwd=cwd,
                              stdin=subprocess.DEVNULL, env=env or user_env(), timeout=CASE_TIMEOUT_S,
                              check=False)
    except subprocess.TimeoutExpired as exc:
        pytest.fail(f"umlbot {' '.join(args)} still ran after {CASE_TIMEOUT_S} s: {exc.stderr!r}")
    return Outcome(done.returncode, done.stdout, done.stderr, time.monotonic() - started)


#: a model problem: check, compile and render print every one of them, then one summary line
DIAGNOSTIC = re.compile(r"^\S+:\d+:\d+: (error|warning): ")


def message_lines(stderr: str) -> list[str]:
    """stderr without structured log lines (JSON), click's usage preamble and model diagnostics."""
    return [
        line for line in stderr.splitlines()
        if line.strip() and not line.startswith(("{", "Usage: ", "Try '")) and not DIAGNOSTIC.match(line)
    ]


def assert_one_clear_line(outcome: Outcome, code: int, *expected: str) -> str:
    assert "Traceback" not in outcome.stderr, outcome.stderr
    assert PASSWORD not in outcome.stderr + outcome.stdout
    assert outcome.code == code, (outcome.code, outcome.stderr)
    lines = message_lines(outcome.stderr)
    assert len(lines) == 1, outcome.stderr
    for text in expected:
        assert text in outcome.stderr or text in outcome.stdout, (text, outcome.stderr, outcome.stdout)
    assert outcome.seconds < CASE_TIMEOUT_S
    return lines[0]


# --- the files a careless user hands over ------------------------------------------------------------

def make_files(folder: Path) -> None:
    (folder / "adir").mkdir()
    (folder / "wrong.json").write_text('{"a": 1}\n')
    (folder / "list.json").write_text("[1, 2]\n")
    (folder / "newer.json").write_text('{"format_version": 999}\n')
    (folder / "garbage.txt").write_text("not json at all\n")
    (folder / "binary.bin").write_bytes(b"\xff\xfe\x00\x81 binary")
    # a bad byte after valid text: line 2, column 15 (the "é" is one character of two bytes)
    (folder / "bad_byte.yaml").write_bytes(b"# a\ncomponents: {\xc3\xa9\xff}\n")
    (folder / "bad_byte.jsonl").write_bytes(b'\n\n{"lane": "\xc3\xa9\xff"}\n')  # line 3, column 12
    (folder / "bad.yaml").write_text("components: [\n")
    (folder / "unknown_impl.yaml").write_text("components:\n  LeftActuator: {impl: warpdrive}\n")
    (folder / "unknown_impl.txt").write_text("LeftActuator=CModelWarpDrive\n")
    (folder / "unknown_driver.yaml").write_text(
        "components:\n  LeftActuator: {impl: l298n, driver: steam, settings: {in1: 22, in2: 23}}\n")
    (folder / "only_motor.yaml").write_text(
        "components:\n  LeftActuator: {impl: l298n, settings: {in1: 22, in2: 23}}\n")
    reference = Path(DEPLOYMENT).read_text()
    (folder / "shared_pin.yaml").write_text(reference.replace("in1: 24", "in1: 22"))
    (folder / "track_wrong.yaml").write_text("name: t\nstart: {x: 0, y: 0}\n")
    (folder / "trace_no_node.jsonl").write_text('{"lane": "LeftActuator"}\n')
    (folder / "passwd").write_text("robot-without-a-hash\n")
    (folder / "acl_wrong.yaml").write_text("[1, 2]\n")
    (folder / "acl_not_list.yaml").write_text("acl:\n  robot: umlbot/#\n")
    (folder / "acl_extra.yaml").write_text("acl: {robot: ['umlbot/#']}\nsubscribe: {}\n")
    (folder / "track_bad_wall.yaml").write_text("walls: [[0, 0, 1]]\n")
    compiled = subprocess.run([UMLBOT, "compile", MODEL, "-o", "-"], capture_output=True, check=True,
                              env=user_env()).stdout
    (folder / "good.json").write_bytes(compiled)
    (folder / "truncated.json").write_bytes(compiled[: len(compiled) // 2])


DEAD = "mqtt://127.0.0.1:{dead}"  # a port nothing listens on
SECRET_DEAD = f"mqtt://robot:{PASSWORD}@127.0.0.1:{{dead}}"

#: id, arguments ({f} = the folder of bad files), exit status, texts the message line must hold
CASES: list[tuple[str, list[str], int, list[str]]] = [
    # the group
    ("unknown-command", ["launch"], 2, ["No such command 'launch'"]),
    ("bad-log-level", ["--log-level", "LOUD", "check", MODEL], 2, ["--log-level", "'LOUD'"]),
    # check
    ("check-missing", ["check", "{f}/nope"], 2, ["MODEL", "nope", "does not exist"]),
    ("check-folder-without-model", ["check", "{f}/adir"], 1, ["adir:1:1", "no model.yaml"]),
    ("check-binary", ["check", "{f}/binary.bin"], 1, ["binary.bin:1:1", "not UTF-8"]),
    ("check-bad-byte", ["check", "{f}/bad_byte.yaml"], 1,
     ["bad_byte.yaml:2:15: error: not UTF-8 text: byte 0xff: invalid start byte"]),
    ("check-compiled-file", ["check", "{f}/good.json"], 1, ["good.json:1:1", "compiled model file"]),
    ("check-unknown-impl", ["check", MODEL, "--deployment", "{f}/unknown_impl.yaml"], 1,
     ["unknown_impl.yaml:2", "unknown implementation id 'warpdrive'"]),
    # compile
    ("compile-missing", ["compile", "{f}/nope", "-o", "{f}/x.json"], 2, ["does not exist"]),
    ("compile-output-is-folder", ["compile", MODEL, "-o", "{f}/adir"], 2, ["adir' is a directory"]),
    ("compile-output-unwritable", ["compile", MODEL, "-o", "{f}/binary.bin/x.json"], 1,
     ["cannot write", "binary.bin/x.json", "binary.bin is not a folder"]),
    ("compile-bad-model", ["compile", "{f}/wrong.json", "-o", "{f}/x.json"], 1, ["nothing written"]),
    # render
    ("render-missing", ["render", "{f}/nope"], 2, ["does not exist"]),
    ("render-output-is-file", ["render", MODEL, "-o", "{f}/wrong.json"], 2, ["is a file"]),
    ("render-output-unwritable", ["render", MODEL, "--format", "mermaid", "-o", "{f}/binary.bin/d"], 1,
     ["binary.bin", "Not a directory"]),
    # run
    ("run-missing", ["run", "{f}/nope"], 2, ["COMPILED", "does not exist"]),
    ("run-folder", ["run", "{f}/adir"], 2, ["is a directory"]),
    ("run-wrong-shape", ["run", "{f}/wrong.json"], 1, ["wrong.json", "not a compiled model"]),
    ("run-json-list", ["run", "{f}/list.json"], 1, ["list.json", "not a compiled model"]),
    ("run-newer-version", ["run", "{f}/newer.json"], 1, ["newer.json", "version 999", "upgrade"]),
    ("run-bad-byte", ["run", "{f}/bad_byte.yaml"], 1,
     ["bad_byte.yaml:2:15: not a compiled model (not UTF-8 text: byte 0xff: invalid start byte)"]),
    ("run-truncated", ["run", "{f}/truncated.json"], 1, ["truncated.json", "not JSON"]),
    ("run-source-not-compiled", ["run", "{f}/bad.yaml"], 1, ["bad.yaml", "not a compiled model"]),
    ("run-url-no-host", ["run", "{f}/good.json", "--broker", "mqtt://"], 1, ["mqtt://", "no host"]),
    ("run-url-http", ["run", "{f}/good.json", "--broker", f"http://u:{PASSWORD}@x"], 1, ["scheme"]),
    ("run-url-port", ["run", "{f}/good.json", "--broker", "mqtt://h:99999"], 1, ["mqtt://h:99999"]),
    ("run-bad-robot", ["run", "{f}/good.json", "--robot", "car/#"], 1, ["robot id 'car/#'"]),
    ("run-unreachable", ["run", "{f}/good.json", "--broker", SECRET_DEAD], 1,
     ["cannot connect", "127.0.0.1"]),
    # call
    ("call-no-dot", ["call", "Foo"], 2, ["Component.feature", "'Foo'"]),
    ("call-no-component", ["call", ".x"], 2, ["Component.feature", "'.x'"]),
    ("call-no-feature", ["call", "A."], 2, ["Component.feature", "'A.'"]),
    ("call-url-http", ["call", "A.b", "--broker", f"http://u:{PASSWORD}@x"], 1, ["scheme"]),
    ("call-url-port", ["call", "A.b", "--broker", "mqtt://h:99999"], 1, ["mqtt://h:99999"]),
    ("call-bad-robot", ["call", "A.b", "--robot", "a+b"], 1, ["robot id 'a+b'"]),
    ("call-wildcard-component", ["call", "Left+.dutycycle", "60", "--broker", DEAD], 2,
     ["component 'Left+' cannot be used in an MQTT topic"]),
    ("call-hash-component", ["call", "Left#.dutycycle", "60", "--broker", DEAD], 2, ["component 'Left#'"]),
    ("call-slash-component", ["call", "a/b.dutycycle", "60", "--broker", DEAD], 2, ["component 'a/b'"]),
    ("call-slash-feature", ["call", "LeftActuator.x/y", "--broker", DEAD], 2, ["feature 'x/y'"]),
    ("call-space-feature", ["call", "LeftActuator.du ty", "--broker", DEAD], 2, ["feature 'du ty'"]),
    ("call-nan-arg", ["call", "A.b", "NaN", "--broker", DEAD], 2, ["'NaN'", "not JSON"]),
    ("call-infinity-arg", ["call", "A.b", "[1, -Infinity]", "--broker", DEAD], 2, ["-Infinity is not JSON"]),
    ("call-huge-number-arg", ["call", "A.b", "1e400", "--broker", DEAD], 2, ["number out of range: 1e400"]),
    ("call-deep-arg", ["call", "A.b", "[" * 3000, "--broker", DEAD], 2, ["nested too deeply"]),
    ("call-timeout-inf", ["call", "A.b", "--timeout", "inf", "--broker", DEAD], 2,
     ["--timeout", "'inf' is not a finite number"]),
    ("call-timeout-huge", ["call", "A.b", "--timeout", "1e10", "--broker", DEAD], 2, ["--timeout", "range"]),
    ("call-timeout-nan", ["call", "A.b", "--timeout", "nan", "--broker", DEAD], 2, ["--timeout", "'nan'"]),
    ("call-connect-timeout-1e400", ["call", "A.b", "--connect-timeout", "1e400", "--broker", DEAD], 2,
     ["--connect-timeout", "not a finite number"]),
    ("call-unreachable", ["call", "A.b", "--broker", SECRET_DEAD, "--connect-timeout", "0.5"], 4,
     ["not_connected", "cannot connect"]),
    # service
    ("service-unknown-kind", ["service", "laser", "--deploy", DEPLOYMENT], 2, ["'laser' is not one of"]),
    ("service-no-deploy", ["service", "motor"], 2, ["--deploy"]),
    ("service-deploy-missing", ["service", "motor", "--deploy", "{f}/nope"], 1,
     ["cannot read deployment", "nope"]),
    ("service-deploy-folder", ["service", "motor", "--deploy", "{f}/adir"], 2, ["is a directory"]),
    ("service-deploy-binary", ["service", "motor", "--deploy", "{f}/binary.bin"], 1,
     ["binary.bin:1:1: cannot read deployment: not UTF-8 text: byte 0xff"]),
    ("service-deploy-bad-byte", ["service", "motor", "--deploy", "{f}/bad_byte.yaml"], 1,
     ["bad_byte.yaml:2:15: cannot read deployment: not UTF-8 text: byte 0xff: invalid start byte"]),
    ("service-deploy-bad-yaml", ["service", "motor", "--deploy", "{f}/bad.yaml"], 1,
     ["bad.yaml:2:1: not valid YAML"]),
    ("service-deploy-wrong-shape", ["service", "motor", "--deploy", "{f}/wrong.json"], 1,
     ["wrong.json", "invalid deployment"]),
    ("service-unknown-impl", ["service", "motor", "--deploy", "{f}/unknown_impl.yaml"], 1,
     ["unknown_impl.yaml:2:18: ", "'LeftActuator'", "unknown implementation id 'warpdrive'"]),
    ("service-unknown-impl-plain", ["service", "motor", "--deploy", "{f}/unknown_impl.txt"], 1,
     ["unknown_impl.txt", "'CModelWarpDrive'"]),
    ("service-shared-pin", ["service", "motor", "--deploy", "{f}/shared_pin.yaml", "--driver", "pigpio",
                            "--broker", DEAD], 1,
     ["shared_pin.yaml:15:16: GPIO 22 ('in1' of 'RightActuator') is already wired to 'LeftActuator' ('in1'): "
      "each pin belongs to one component"]),
    ("service-model-as-deployment", ["service", "motor", "--deploy", MODEL + "/model.yaml"], 1,
     ["model.yaml:7:3: invalid deployment: components.RaspberryPI.impl: Field required (and 16 more",
      "is this a deployment?"]),
    ("service-no-such-kind-deployed", ["service", "sonar", "--deploy", "{f}/only_motor.yaml"], 1,
     ["no component served by the sonar service"]),
    ("service-unknown-driver", ["service", "motor", "--deploy", DEPLOYMENT, "--driver", "steam"], 1,
     ["unknown motor driver 'steam'", "mock"]),
    ("service-unknown-driver-deployed", ["service", "motor", "--deploy", "{f}/unknown_driver.yaml",
                                         "--broker", DEAD], 1,
     ["unknown_driver.yaml:2:31: unknown motor driver 'steam'"]),
    ("service-unknown-component", ["service", "motor", "--deploy", DEPLOYMENT, "--component", "Sensor"],
     1, ["no motor component(s) ['Sensor']"]),
    ("service-unreachable", ["service", "motor", "--deploy", DEPLOYMENT, "--driver", "mock",
                             "--broker", SECRET_DEAD, "--connect-timeout", "0.5"], 1, ["cannot connect"]),
    # sim
    ("sim-missing-model", ["sim", "{f}/nope"], 2, ["does not exist"]),
    ("sim-not-a-model", ["sim", "{f}/adir", "--track", TRACK, "--port", "0"], 1, ["adir", "no model.yaml"]),
    ("sim-compiled-file", ["sim", "{f}/good.json", "--track", TRACK, "--port", "0"], 1,
     ["good.json:1:1", "compiled model file", "umlbot run"]),
    ("sim-missing-track", ["sim", MODEL, "--track", "{f}/nope.yaml", "--port", "0"], 1,
     ["no track file", "nope.yaml': no such file"]),
    ("sim-unknown-track-name", ["sim", MODEL, "--track", "corridoor", "--port", "0"], 1,
     ["no track 'corridoor': no such file, and no bundled track of that name", "corridor"]),
    ("sim-track-folder", ["sim", MODEL, "--track", "{f}/adir"], 2, ["is a directory"]),
    ("sim-track-bad-yaml", ["sim", MODEL, "--track", "{f}/bad.yaml", "--port", "0"], 1,
     ["bad.yaml:2:1: not valid YAML"]),
    ("sim-track-wrong-shape", ["sim", MODEL, "--track", "{f}/track_wrong.yaml", "--port", "0"], 1,
     ["track_wrong.yaml:1:1: invalid track: goal: Field required; walls: Field required (1:1)"]),
    ("sim-track-bad-wall", ["sim", MODEL, "--track", "{f}/track_bad_wall.yaml", "--port", "0"], 1,
     ["track_bad_wall.yaml:1:1: invalid track: name: Field required;", "walls.0: Value error, a wall is a "
      "list of [x, y] points, such as [[0, 0], [1, 0]], not one point [0, 0, 1] (1:9)"]),
    ("sim-track-binary", ["sim", MODEL, "--track", "{f}/binary.bin", "--port", "0"], 1,
     ["binary.bin:1:1: cannot read track: not UTF-8 text: byte 0xff"]),
    ("sim-track-bad-byte", ["sim", MODEL, "--track", "{f}/bad_byte.yaml", "--port", "0"], 1,
     ["bad_byte.yaml:2:15: cannot read track: not UTF-8 text: byte 0xff: invalid start byte"]),
    ("sim-plot-suffix", ["sim", MODEL, "--track", TRACK, "--port", "0", "--plot", "{f}/run.txt"], 1,
     ["run.txt", ".png"]),
    ("sim-url-http", ["sim", MODEL, "--track", TRACK, "--broker", "http://x"], 1, ["scheme"]),
    # broker
    ("broker-port", ["broker", "--port", "99999"], 2, ["--port", "99999"]),
    ("broker-bind", ["broker", "--bind", "256.0.0.1", "--port", "0"], 1, ["cannot listen on 256.0.0.1"]),
    ("broker-hash-bad-user", ["broker", "--hash-password", "robot:1"], 1, ["'robot:1'", "no ':'"]),
    ("broker-passwd-missing", ["broker", "--passwd", "{f}/nope", "--port", "0"], 1, ["does not exist"]),
    ("broker-passwd-malformed", ["broker", "--passwd", "{f}/passwd", "--port", "0"], 1,
     ["passwd:1", "user:<argon2 hash>"]),
    ("broker-acl-bad-yaml", ["broker", "--acl", "{f}/bad.yaml", "--port", "0"], 1,
     ["bad.yaml:2:1: not valid YAML"]),
    ("broker-acl-bad-byte", ["broker", "--acl", "{f}/bad_byte.yaml", "--port", "0"], 1,
     ["bad_byte.yaml:2:15: cannot read ACL file: not UTF-8 text: byte 0xff: invalid start byte"]),
    ("broker-passwd-bad-byte", ["broker", "--passwd", "{f}/bad_byte.yaml", "--port", "0"], 1,
     ["bad_byte.yaml:2:15: cannot read password file: not UTF-8 text: byte 0xff"]),
    ("broker-acl-wrong-shape", ["broker", "--acl", "{f}/acl_wrong.yaml", "--port", "0"], 1,
     ["acl_wrong.yaml:1:1: invalid ACL file", "publish_acl"]),
    ("broker-acl-not-a-list", ["broker", "--acl", "{f}/acl_not_list.yaml", "--port", "0"], 1,
     ["acl_not_list.yaml:2:3: invalid ACL file: acl.robot: Input should be a valid list",
      "topic filters are a list"]),
    ("broker-acl-unknown-key", ["broker", "--acl", "{f}/acl_extra.yaml", "--port", "0"], 1,
     ["acl_extra.yaml:2:1: invalid ACL file: subscribe: Extra inputs are not permitted (allowed keys: acl,"]),
    # monitor
    ("monitor-replay-missing", ["monitor", "--replay", "{f}/nope", "--json"], 1, ["cannot read trace file"]),
    ("monitor-replay-folder", ["monitor", "--replay", "{f}/adir"], 2, ["is a directory"]),
    ("monitor-replay-garbage", ["monitor", "--replay", "{f}/garbage.txt", "--json"], 1,
     ["garbage.txt:1: not a trace event"]),
    ("monitor-replay-no-node", ["monitor", "--replay", "{f}/trace_no_node.jsonl", "--json"], 1,
     ["trace_no_node.jsonl:1", "node: Field required"]),
    ("monitor-replay-binary", ["monitor", "--replay", "{f}/binary.bin", "--json"], 1,
     ["binary.bin:1:1: cannot read trace file: not UTF-8 text: byte 0xff"]),
    ("monitor-replay-bad-byte", ["monitor", "--replay", "{f}/bad_byte.jsonl", "--json"], 1,
     ["bad_byte.jsonl:3:12: cannot read trace file: not UTF-8 text: byte 0xff: invalid start byte"]),
    ("monitor-url-http", ["monitor", "--broker", "http://x"], 1, ["scheme"]),
    ("monitor-duration-nan", ["monitor", "--duration", "nan", "--broker", DEAD, "--json"], 2,
     ["--duration", "'nan' is not a finite number"]),
    ("monitor-speed-inf", ["monitor", "--replay", "{f}/garbage.txt", "--speed", "inf"], 2, ["--speed"]),
    ("run-call-timeout-inf", ["run", "{f}/good.json", "--call-timeout", "inf", "--broker", DEAD], 2,
     ["--call-timeout", "not a finite number"]),
    ("run-grace-nan", ["run", "{f}/good.json", "--grace", "nan", "--broker", DEAD], 2, ["--grace"]),
    ("run-startup-timeout-inf", ["run", "{f}/good.json", "--startup-timeout", "inf"], 2,
     ["--startup-timeout"]),
    ("service-connect-timeout-nan", ["service", "motor", "--deploy", DEPLOYMENT, "--connect-timeout", "nan"],
     2, ["--connect-timeout"]),
    ("sim-timeout-inf", ["sim", MODEL, "--timeout", "inf", "--broker", DEAD], 2,
     ["--timeout", "'inf' is not a finite number"]),
    ("sim-noise-nan", ["sim", MODEL, "--noise", "nan", "--broker", DEAD], 2, ["--noise", "'nan'"]),
    ("sim-drop-nan", ["sim", MODEL, "--drop", "nan", "--broker", DEAD], 2, ["--drop"]),
    ("sim-speed-inf", ["sim", MODEL, "--speed", "inf", "--broker", DEAD], 2, ["--speed"]),
    ("monitor-bad-robot", ["monitor", "--robot", "car/#", "--broker", DEAD, "--json"], 1,
     ["robot id 'car/#'"]),
    ("monitor-unreachable", ["monitor", "--broker", SECRET_DEAD, "--json", "--connect-timeout", "0.5"], 1,
     ["cannot connect"]),
]


@pytest.fixture(scope="module")
def outcomes(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Outcome]:
    """Every case of the table, run four at a time."""
    folder = tmp_path_factory.mktemp("bad-input")
    make_files(folder)
    dead = str(free_port())

    def one(case: tuple[str, list[str], int, list[str]]) -> tuple[str, Outcome]:
        name, args = case[0], [a.format(f=folder, dead=dead) for a in case[1]]
        return name, run_umlbot(args, folder)

    with ThreadPoolExecutor(max_workers=4) as pool:
        return dict(pool.map(one, CASES))


@pytest.mark.parametrize(("name", "code", "expected"), [(c[0], c[2], c[3]) for c in CASES],
                         ids=[c[0] for c in CASES])
def test_bad_input(outcomes: dict[str, Outcome], name: str, code: int, expected: list[str]) -> None:
    assert_one_clear_line(outcomes[name], code, *expected)


def test_a_setting_the_driver_refuses_is_named_at_its_position(tmp_path: Path) -> None:
    deploy = tmp_path / "pin99.yaml"
    deploy.write_text(Path(DEPLOYMENT).read_text().replace("in1: 24", "in1: 99"))
    outcome = run_umlbot(["service", "all", "--deploy", str(deploy), "--driver", "pigpio", "--broker",
                          f"mqtt://127.0.0.1:{free_port()}"], tmp_path, user_env(UMLBOT_FAKE_PIGPIO="1"))
    assert_one_clear_line(
        outcome, 1, "pin99.yaml:15:16: component RightActuator: settings.in1: Input should be less than or "
        "equal to 27")


def test_compile_makes_a_missing_output_folder(tmp_path: Path) -> None:
    target = tmp_path / "new" / "dir" / "x.json"
    outcome = run_umlbot(["compile", MODEL, "-o", str(target)], tmp_path)
    assert outcome.code == 0, outcome.stderr
    assert json.loads(target.read_text())["format_version"] >= 1


def test_a_failed_compile_keeps_the_previous_output(tmp_path: Path) -> None:
    target = tmp_path / "car.json"
    target.write_text("the previous compiled model\n")
    (tmp_path / "broken").mkdir()
    outcome = run_umlbot(["compile", str(tmp_path / "broken"), "-o", str(target)], tmp_path)
    assert outcome.code == 1 and "nothing written" in outcome.stderr
    assert target.read_text() == "the previous compiled model\n"
    outcome = run_umlbot(["compile", MODEL, "-o", str(tmp_path / "car.json" / "x")], tmp_path)
    assert outcome.code == 1
    assert target.read_text() == "the previous compiled model\n"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["broken", "car.json"]  # no temporary left


# --- with a broker: bad calls, taken ports, nothing online -------------------------------------------

@pytest.fixture(scope="module")
def shared_broker(tmp_path_factory: pytest.TempPathFactory) -> Iterator[BrokerProcess]:
    yield from _broker("amqtt", tmp_path_factory)


@pytest.fixture(scope="module")
def motor_service(shared_broker: BrokerProcess) -> Iterator[str]:
    """The real motor service with mock drivers for robot `badinput`."""
    host = ServiceHost("motor", load_deployment(DEPLOYMENT), BrokerSettings.from_url(shared_broker.url),
                       "badinput", "mock", connect_timeout_s=5.0)
    host.start()
    yield shared_broker.url
    host.stop()


@pytest.mark.parametrize(
    ("args", "code"),
    [
        (["LeftActuator.dutycycle", "{bad"], "bad_args"),        # not JSON: sent as a string
        (["LeftActuator.dutycycle", "150"], "out_of_range"),
        (["LeftActuator.dutycycle", "1", "2"], "bad_args"),
        (["LeftActuator.fly"], "unknown_feature"),
    ],
    ids=["not-json", "out-of-range", "too-many", "unknown-feature"],
)
def test_bad_call_gets_an_error_reply(motor_service: str, args: list[str], code: str) -> None:
    outcome = run_umlbot(["call", "--robot", "badinput", "--broker", motor_service, *args], REPO)
    line = assert_one_clear_line(outcome, 1, code)
    assert line.startswith(f"{code}: ")
    reply = json.loads(outcome.stdout)
    assert reply["ok"] is False and reply["error"]["code"] == code
    # the service took no harm: a good call still works
    good = run_umlbot(["call", "--robot", "badinput", "--broker", motor_service, "LeftActuator.enabled",
                       "false"], REPO)
    assert good.code == 0, good.stderr
    assert json.loads(good.stdout) == {"ok": True, "value": None}


def test_call_nobody_answers(shared_broker: BrokerProcess) -> None:
    outcome = run_umlbot(["call", "--robot", "nobody", "--broker", shared_broker.url, "--timeout", "0.5",
                          "Ghost.value"], REPO)
    assert_one_clear_line(outcome, 3, "timeout", "Ghost.value")


def test_tls_url_to_a_plain_broker_gives_up_in_time(shared_broker: BrokerProcess) -> None:
    outcome = run_umlbot(["call", "--broker", f"mqtts://127.0.0.1:{shared_broker.port}", "--connect-timeout",
                          "1", "A.b"], REPO)
    assert_one_clear_line(outcome, 4, "not_connected", "mqtts://127.0.0.1",
                          "is that port TLS? (mqtts:// needs a TLS listener")
    assert outcome.seconds < 4.0  # the TLS handshake that never ends is not waited for


def test_tls_url_to_a_closed_port_gets_no_tls_hint() -> None:
    outcome = run_umlbot(["call", "--broker", f"mqtts://127.0.0.1:{free_port()}", "--connect-timeout",
                          "1", "A.b"], REPO)
    line = assert_one_clear_line(outcome, 4, "not_connected", "is it running?")
    assert "TLS" not in line


@pytest.mark.parametrize("command", ["broker", "sim"])
def test_taken_port(shared_broker: BrokerProcess, command: str) -> None:
    args = ["broker"] if command == "broker" else ["sim", MODEL, "--track", TRACK]
    outcome = run_umlbot([*args, "--port", str(shared_broker.port)], REPO)
    assert_one_clear_line(outcome, 1, f"port {shared_broker.port}", "already in use", "--broker")


def test_run_with_no_service_online(shared_broker: BrokerProcess, tmp_path: Path) -> None:
    compiled = tmp_path / "car.json"
    subprocess.run([UMLBOT, "compile", MODEL, "-o", str(compiled)], check=True, capture_output=True)
    outcome = run_umlbot(["run", str(compiled), "--broker", shared_broker.url, "--robot", "lonely",
                          "--startup-timeout", "1"], tmp_path)
    assert_one_clear_line(outcome, 1, "not online", "LeftActuator", "umlbot service")


def test_log_level_error_prints_a_fatal_error_once(shared_broker: BrokerProcess, tmp_path: Path) -> None:
    compiled = tmp_path / "car.json"
    subprocess.run([UMLBOT, "compile", MODEL, "-o", str(compiled)], check=True, capture_output=True)
    outcome = run_umlbot(["--log-level", "ERROR", "run", str(compiled), "--broker", shared_broker.url,
                          "--robot", "quiet", "--startup-timeout", "1"], tmp_path)
    assert outcome.code == 1
    lines = outcome.stderr.splitlines()
    assert len(lines) == 1 and lines[0].startswith("error: "), outcome.stderr
    assert "not online" in lines[0]


# --- Ctrl-C at start-up ------------------------------------------------------------------------------

def interrupt_at(args: list[str], marker: str, cwd: Path) -> tuple[Outcome, float]:
    """Start umlbot, send SIGINT once `marker` appeared in its output; (outcome, seconds after SIGINT)."""
    proc = subprocess.Popen([UMLBOT, *args], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                            cwd=cwd, env=user_env(UMLBOT_LOG_LEVEL="DEBUG"))
    seen = threading.Event()
    chunks: dict[str, list[str]] = {"out": [], "err": []}

    def read(stream: object, key: str) -> None:
        for line in stream:  # type: ignore[attr-defined]
            chunks[key].append(line)
            if marker in line:
                seen.set()

    readers = [threading.Thread(target=read, args=(proc.stdout, "out"), daemon=True),
               threading.Thread(target=read, args=(proc.stderr, "err"), daemon=True)]
    for reader in readers:
        reader.start()
    try:
        assert seen.wait(CASE_TIMEOUT_S), f"no {marker!r} from umlbot {args}: {''.join(chunks['err'])}"
        time.sleep(0.3)  # the line is logged a moment before the command leaves the step it names
        proc.send_signal(signal.SIGINT)
        sent = time.monotonic()
        code = proc.wait(CASE_TIMEOUT_S)
        waited = time.monotonic() - sent
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    for reader in readers:
        reader.join(5)
    return Outcome(code, "".join(chunks["out"]), "".join(chunks["err"]), waited), waited


@pytest.mark.parametrize(
    ("args", "marker", "code", "message"),
    [
        (["broker", "--port", "0"], "listening on", 0, None),
        (["service", "motor", "--deploy", DEPLOYMENT, "--driver", "mock", "--broker", DEAD,
          "--connect-timeout", "12"], "mqtt_connect_failed", 130, "aborted"),
        (["monitor", "--json", "--broker", DEAD, "--connect-timeout", "12"], "mqtt_connect_failed", 130,
         "aborted"),
        (["run", "{compiled}", "--broker", DEAD], "mqtt_connect_failed", 0, None),
        (["run", "{compiled}", "--broker", "{broker}", "--robot", "sigint", "--startup-timeout", "12"],
         "mqtt_connected", 0, None),
        (["service", "motor", "--deploy", DEPLOYMENT, "--driver", "mock", "--broker", "{broker}",
          "--robot", "sigint"], "service_started", 0, None),
        (["sim", MODEL, "--track", TRACK, "--broker", DEAD], "mqtt_connect_failed", 1, None),
        (["sim", MODEL, "--track", TRACK, "--port", "0", "--speed", "1"], "broker mqtt://", 1, None),
    ],
    ids=["broker", "service-connecting", "monitor-connecting", "run-connecting", "run-waiting-for-services",
         "service-running", "sim-connecting", "sim-running"],
)
def test_ctrl_c_at_start_up(shared_broker: BrokerProcess, tmp_path: Path, args: list[str], marker: str,
                            code: int, message: str | None) -> None:
    compiled = tmp_path / "car.json"
    if "{compiled}" in args:
        subprocess.run([UMLBOT, "compile", MODEL, "-o", str(compiled)], check=True, capture_output=True)
    argv = [a.format(dead=free_port(), broker=shared_broker.url, compiled=compiled) for a in args]
    outcome, waited = interrupt_at(argv, marker, tmp_path)
    assert "Traceback" not in outcome.stderr, outcome.stderr
    assert outcome.code == code, outcome.stderr
    assert waited < 5.0, f"took {waited:.1f} s to stop after SIGINT"
    if message is not None:
        assert message_lines(outcome.stderr) == [message]
    if argv[0] == "sim":
        assert "interrupted" in outcome.stdout
