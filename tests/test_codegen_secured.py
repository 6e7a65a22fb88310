"""Both engines on the shipped secured Mosquitto: user:password from UMLBOT_BROKER, and mqtts://
with the CA, the orchestrator's own user and ACL (deploy/mosquitto); mock services as their users."""

from __future__ import annotations

import os
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path

import pytest
from codegen_support import TEST_MODELS, built_programs
from orchestrator_support import deployment_of
from secured_brokers import AuthFiles, SecuredBroker, make_auth_files, start_secured, stop_broker

from umlbot.compiler.api import compile_model
from umlbot.compiler.compiled import write_compiled
from umlbot.services.bus import BrokerSettings
from umlbot.services.host import ServiceHost

pytestmark = [pytest.mark.network, pytest.mark.timeout(600)]


@pytest.fixture(scope="module")
def auth(tmp_path_factory: pytest.TempPathFactory) -> AuthFiles:
    return make_auth_files(tmp_path_factory.mktemp("auth"), tmp_path_factory.mktemp("certs"))


@pytest.fixture
def secured(tmp_path: Path, auth: AuthFiles) -> Iterator[SecuredBroker]:
    broker = start_secured("mosquitto", tmp_path, auth)
    try:
        yield broker
    finally:
        stop_broker(broker)


@pytest.mark.parametrize("engine", ["python", "cpp"])
@pytest.mark.parametrize("tls", [False, True], ids=["password", "mqtts"])
def test_the_fork_model_runs_on_the_secured_broker(engine: str, tls: bool, secured: SecuredBroker,
                                                    tmp_path: Path) -> None:
    model = compile_model(TEST_MODELS["fork"])
    service_url = f"mqtt://umlbot-motor:{secured.passwords['motor']}@127.0.0.1:{secured.port}"
    host = ServiceHost("motor", deployment_of(model), BrokerSettings.from_url(service_url), "car",
                       driver="mock")
    host.start()
    try:
        password = secured.passwords["orchestrator"]
        if tls:
            url = f"mqtts://umlbot-orchestrator:{password}@127.0.0.1:{secured.tls_port}?ca={secured.ca_file}"
        else:
            url = f"mqtt://umlbot-orchestrator:{password}@127.0.0.1:{secured.port}"
        if engine == "cpp":
            argv = [str(built_programs()["fork"])]
        else:
            compiled = tmp_path / "fork.json"
            write_compiled(model, compiled)
            argv = [sys.executable, "-c", "from umlbot.cli import main; main()", "run", str(compiled)]
        env = {**os.environ, "UMLBOT_BROKER": url, "UMLBOT_LOG_LEVEL": "WARNING"}
        done = subprocess.run([*argv, "--robot", "car", "--startup-timeout", "5"], capture_output=True,
                              text=True, timeout=60, check=False, env=env)
        assert done.returncode == 0, done.stderr[-3000:]
        assert password not in done.stderr
        assert host.drivers["LeftActuator"].commands_named("set_duty_cycle") == [(10,)]
        assert host.drivers["RightActuator"].commands_named("set_duty_cycle") == [(20,)]
    finally:
        host.stop()
