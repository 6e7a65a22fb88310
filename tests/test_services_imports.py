"""What a hardware service process imports (docs/performance.md, "Memory").

A real `umlbot service` runs against Mosquitto, answers a good and a bad call (request validation
and the warning log line run), and then lists its `sys.modules`: the libraries the service does
not use at run time must not be there, and the ones the issue keeps (pydantic at the boundary,
structlog, paho, click) must. bench/memory.py measures the megabytes; this guards the cause
cheaply and without a flaky RSS threshold.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
import time
import zoneinfo
from pathlib import Path

import pytest
from conftest import BrokerProcess

from umlbot.base.errors import RemoteError
from umlbot.services.bus import BrokerSettings, BusClient, Message, Topics

ROOT = Path(__file__).resolve().parent.parent
DEPLOYMENT = ROOT / "models" / "robot_car" / "deployment.yaml"
ROBOT = "importcheck"

#: `umlbot service` reads its command line and deployment, then replaces itself (same PID) with
#: the serving process `python -m umlbot.services.serve` (docs/services.md). This
#: `sitecustomize`, put on PYTHONPATH, runs in both; in the serving one (the handover is in its
#: environment) it writes to $IMPORTCHECK_OUT, once $IMPORTCHECK_TRIGGER exists, what a service
#: that has been serving holds: its PID, sorted(sys.modules) and the pydantic models whose
#: validator is built (module.qualname), as JSON.
SITECUSTOMIZE = """
import os
if os.environ.get("UMLBOT_SERVICE_HANDOVER") and os.environ.get("IMPORTCHECK_OUT"):
    import json, sys, threading, time
    trigger, out = os.environ["IMPORTCHECK_TRIGGER"], os.environ["IMPORTCHECK_OUT"]
    def built_models():
        from pydantic import BaseModel
        seen, todo = set(), list(BaseModel.__subclasses__())
        while todo:
            model = todo.pop()
            if model not in seen:
                seen.add(model)
                todo.extend(model.__subclasses__())
        built = [m for m in seen if m.__dict__.get("__pydantic_complete__")]
        return sorted(f"{m.__module__}.{m.__qualname__}" for m in built)
    def dump():
        while not os.path.exists(trigger):
            time.sleep(0.02)
        zoneinfo = sys.modules.get("zoneinfo")
        state = {"pid": os.getpid(), "modules": sorted(sys.modules), "models": built_models(),
                 "tzpath": None if zoneinfo is None else list(zoneinfo.TZPATH),
                 "environ": sorted(k for k in os.environ if k.startswith(("UMLBOT_SERVICE", "PYTHONTZ")))}
        with open(out + ".part", "w") as file:
            file.write(json.dumps(state))
        os.rename(out + ".part", out)
    threading.Thread(target=dump, daemon=True).start()
"""

#: Imported by other commands only (compiler, simulator, studio, broker, monitor, orchestrator),
#: by libraries only for features a service does not use (asyncio, rich and greenlet by structlog;
#: urllib.request and http.client by paho, for proxies; ssl by paho, for TLS, also where its socket
#: reads and writes name `ssl.SSLWantReadError` in `except` clauses; hashlib by paho for WebSockets
#: and secrets by pydantic for SecretStr; importlib.metadata with email, zipfile and csv by the
#: plugin catalog and pydantic's plugin lookup, which umlbot.base.entrypoints reads without them;
#: tempfile with shutil by umlbot.base.files, only for writing), or by the real GPIO drivers (the
#: mock driver is running). The command line's code — click, PyYAML, umlbot.cli and the commands —
#: stays in the process that read the arguments and the deployment, which the serving one
#: replaced; concurrent.futures with the bus client (a service only serves), random (the
#: reconnect jitter reads os.urandom) and the idna codec (an ASCII broker host is resolved as
#: bytes) neither, nor the YAML positions (rebuilt from the handover only for an error's file:line),
#: nor sysconfig's build data `_sysconfigdata_*` (zoneinfo, which pydantic imports, gets the
#: command's search path in PYTHONTZPATH instead of reading it there).
ABSENT = (
    "asyncio", "rich", "greenlet", "urllib.request", "http.client", "matplotlib", "numpy", "amqtt",
    "aiohttp", "umlbot.compiler.api", "umlbot.compiler.checker", "umlbot.compiler.source",
    "umlbot.compiler.expr_parser", "umlbot.compiler.compiled", "umlbot.compiler.render", "umlbot.sim",
    "umlbot.studio", "umlbot.services.orchestrator", "umlbot.monitor", "umlbot.services.bus.broker",
    "pigpio", "lgpio", "secrets", "hmac", "hashlib", "_hashlib",
    "ssl", "_ssl", "importlib.metadata", "email", "zipfile", "csv", "tempfile", "shutil",
    "click", "yaml", "_yaml", "umlbot.cli", "umlbot.commands", "umlbot.services.bus.client",
    "concurrent.futures", "random", "encodings.idna", "stringprep", "unicodedata", "umlbot.base.yamlsrc",
)
#: What the service keeps on purpose: request validation, logging, the MQTT client, and the
#: serving entry point that took over from the command.
PRESENT = ("pydantic", "umlbot.services.bus.envelopes", "structlog", "paho.mqtt.client",
           "umlbot.services.serve")

#: The pydantic models a service builds (each costs resident memory: docs/performance.md,
#: "Memory"): the payloads of the bus, the broker settings, the deployment, and the settings of its
#: own kinds' drivers — no model of another floor (compiled model, compiler, sim, studio, CLI) and
#: no other kind's settings. These validate at the boundary and must be built:
VALIDATED = ("umlbot.services.bus.envelopes.CallRequest", "umlbot.services.bus.envelopes.Reply",
             "umlbot.services.bus.envelopes.ErrorBody", "umlbot.services.bus.envelopes.Status",
             "umlbot.services.bus.envelopes.Heartbeat", "umlbot.services.bus.settings.BrokerSettings",
             "umlbot.base.deployment.Deployment")
#: modules whose models a service of any kind may build; a kind's own modules come on top
MODEL_MODULES = ("umlbot.base.deployment", "umlbot.services.bus.envelopes", "umlbot.services.bus.settings",
                 "umlbot.services.mock_support", "umlbot.services.serve")


#: The reference car's components by service kind.
COMPONENTS = {"motor": {"LeftActuator", "RightActuator"}, "sonar": {"DistanceRead"}, "servo": {"Sensor"},
              "gpio": {"RaspberryPI"}}


def _wait_online(bus: BusClient, components: set[str], timeout_s: float) -> None:
    """Until every component says `online` on its retained status topic."""
    online: set[str] = set()

    def on_status(message: Message) -> None:
        component = message.topic.split("/")[2]
        if message.payload and json.loads(message.payload).get("state") == "online":
            online.add(component)

    for component in components:
        bus.subscribe(Topics(ROBOT).status(component), on_status)
    deadline = time.monotonic() + timeout_s
    while not components <= online:
        assert time.monotonic() < deadline, f"online: {sorted(online)} of {sorted(components)}"
        time.sleep(0.02)


@pytest.mark.parametrize("kind", ["motor", "all"])
def test_a_serving_service_imports_only_what_it_uses(
    kind: str, mosquitto_broker: BrokerProcess, tmp_path: Path
) -> None:
    trigger, out = tmp_path / "dump-now", tmp_path / "modules.txt"
    (tmp_path / "hook").mkdir()
    (tmp_path / "hook" / "sitecustomize.py").write_text(SITECUSTOMIZE)
    argv = [sys.executable, "-c", "from umlbot.cli import main; main()", "service", kind, "--deploy",
            str(DEPLOYMENT), "--driver", "mock", "--robot", ROBOT, "--broker", mosquitto_broker.url]
    path = os.pathsep.join(filter(None, [str(tmp_path / "hook"), os.environ.get("PYTHONPATH")]))
    inherited = {key: value for key, value in os.environ.items() if key != "PYTHONTZPATH"}
    service = subprocess.Popen(argv, stderr=subprocess.PIPE, text=True,
                               env={**inherited, "UMLBOT_LOG_LEVEL": "INFO", "PYTHONPATH": path,
                                    "IMPORTCHECK_TRIGGER": str(trigger), "IMPORTCHECK_OUT": str(out)})
    try:
        with BusClient(BrokerSettings.from_url(mosquitto_broker.url), ROBOT, role="test") as bus:
            _wait_online(bus, set().union(*COMPONENTS.values()) if kind == "all" else COMPONENTS[kind], 20.0)
            bus.call("LeftActuator", "enabled", True, timeout=2.0)
            with pytest.raises(RemoteError) as bad:
                bus.call("LeftActuator", "enabled", timeout=2.0)  # a missing argument
            assert bad.value.code == "bad_args"
        trigger.touch()
        deadline = time.monotonic() + 10.0
        while not out.exists() and time.monotonic() < deadline:
            time.sleep(0.02)
        state = json.loads(out.read_text())
        modules, models = set(state["modules"]), state["models"]
        # the serving process is the one started: `umlbot service` became it (systemd's main PID)
        assert state["pid"] == service.pid
        with open(f"/proc/{service.pid}/cmdline", "rb") as file:
            cmdline = file.read().split(b"\0")
        # … and still shows `umlbot service KIND …` in its command line (ps, pgrep -f)
        shown = [b"-m", b"umlbot.services.serve", b"umlbot", b"service", kind.encode()]
        assert cmdline[1:6] == shown, cmdline
        # the time zone search path is the one sysconfig gives, and the handover's variables are gone
        assert state["tzpath"] == list(zoneinfo.TZPATH) and state["environ"] == []
    finally:
        service.terminate()
        _, stderr = service.communicate(timeout=15)
    assert service.returncode == 0, stderr[-3000:]
    assert "service_started" in stderr and "Traceback" not in stderr
    loaded = sorted(name for name in modules if name.split(".")[0] in ABSENT or name in ABSENT
                    or any(name.startswith(prefix + ".") for prefix in ABSENT))
    loaded += sorted(name for name in modules if name.startswith("_sysconfigdata"))
    assert loaded == [], f"a {kind} service imported what it does not use: {loaded}"
    assert set(PRESENT) <= modules
    kinds = {"motor", "sonar", "servo", "gpio"} if kind == "all" else {kind}
    foreign = [name for name in models if name.rpartition(".")[0] not in MODEL_MODULES
               and name.split(".")[:3] not in [["umlbot", "services", k] for k in kinds]]
    assert foreign == [], f"a {kind} service built pydantic models it does not validate: {foreign}"
    assert set(VALIDATED) <= set(models), sorted(set(VALIDATED) - set(models))
    # the settings of each of its kinds' drivers (the mock driver runs) are validated too
    assert {f"umlbot.services.{k}.mock" for k in kinds} <= {name.rpartition(".")[0] for name in models}


ASYNC_LOGGING = """
import sys
from umlbot.base.logs import configure_logging, get_logger
assert "asyncio" not in sys.modules, "umlbot.base.logs imported asyncio"
configure_logging("INFO", json=True)
import asyncio
import structlog.stdlib

async def main():
    await get_logger("test.imports").ainfo("async_line", loop=type(asyncio.get_running_loop()).__name__)

asyncio.run(main())
# structlog's own name for asyncio resolves to the one asyncio module of the process
assert structlog.stdlib.asyncio.get_running_loop is asyncio.get_running_loop
"""


def test_structlog_async_methods_still_work_where_asyncio_is_used() -> None:
    """umlbot.base.logs gives structlog asyncio only on first use; its coroutine methods still log."""
    result = subprocess.run([sys.executable, "-c", ASYNC_LOGGING], capture_output=True, text=True,
                            timeout=60, check=False)
    assert result.returncode == 0, result.stderr
    assert '"event": "async_line"' in result.stderr and '"loop": "_UnixSelectorEventLoop"' in result.stderr
