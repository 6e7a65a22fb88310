"""The serving half of `umlbot service KIND`: what runs once the command line is read.

`umlbot service` parses its arguments (click), reads and checks the deployment file (PyYAML, with
`file:line:col` in its errors), the broker URL and the components asked for, exactly as before.
Then, instead of serving in the same interpreter, it replaces itself (`os.execve`: the same PID,
so systemd's main PID, signals, `sd_notify` and the watchdog see the same process) with `python -m
umlbot.services.serve`, handing over what it read and checked as JSON in the environment
(`UMLBOT_SERVICE_HANDOVER`). This module validates that again with the same pydantic models
(`Handover`: the deployment, `BrokerSettings`) and serves. It never imports click, PyYAML nor
the command-line modules, which a serving process would otherwise hold for nothing (about 2 MB
resident of the 30: docs/performance.md, "Memory"). The arguments after the module name are
`umlbot` and the command's own, for `ps`, `pgrep -f "umlbot service motor"` and `systemctl
status` only: nothing reads them here.

Errors end the process as `umlbot` ends it: one `error: …` line and exit 1; `aborted` and exit
130 on a signal during the start.
"""

from __future__ import annotations

import json
import os
import sys
from typing import Any

from pydantic import BaseModel, ConfigDict, Field

from umlbot.base.deployment import Deployment
from umlbot.base.errors import UmlbotError
from umlbot.base.logs import configure_logging
from umlbot.base.stopsignals import StopSignals
from umlbot.services.bus import BrokerSettings

#: the environment variable that carries the handover (removed once read)
HANDOVER_ENV = "UMLBOT_SERVICE_HANDOVER"
#: set when the command gave the serving process its time zone search path (`PYTHONTZPATH`)
TZPATH_ENV = "UMLBOT_SERVICE_TZPATH"
#: a longer handover is not passed (Linux refuses one environment string over 128 KiB): the
#: command then serves in its own interpreter, as before
MAX_HANDOVER = 100_000


class Handover(BaseModel):
    """What `umlbot service` read and checked, for the serving process."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    kinds: tuple[str, ...] = Field(min_length=1)
    #: `Deployment.handover()`: the deployment, its file and the positions of its values
    deployment: dict[str, Any]
    broker: BrokerSettings
    robot: str = Field(min_length=1)
    driver: str | None = None
    components: list[str] | None = None
    connect_timeout_s: float = Field(gt=0, allow_inf_nan=False)
    log_level: str | None = None
    log_json: bool | None = None


def encode(handover: Handover) -> str:
    """The handover as JSON, the broker password included (pydantic's JSON hides it)."""
    data = handover.model_dump(mode="python")  # the deployment's values as read (`inf` stays `inf`)
    data["broker"] = handover.broker.model_dump(mode="json")
    password = handover.broker.password
    data["broker"]["password"] = password.get_secret_value() if password is not None else None
    return json.dumps(data, separators=(",", ":"))


def decode(text: str) -> Handover:
    """The handover `encode` wrote, validated again."""
    return Handover.model_validate(json.loads(text))


def replace_process(handover: Handover, shown_args: list[str]) -> None:
    """Become `python -m umlbot.services.serve` with `handover` (does not return); returns
    without doing anything when the handover is too long for the environment."""
    text = encode(handover)
    if len(text) > MAX_HANDOVER:
        return
    sys.stdout.flush()
    sys.stderr.flush()
    env = {**os.environ, HANDOVER_ENV: text}
    zoneinfo = sys.modules.get("zoneinfo")  # imported by pydantic
    if "PYTHONTZPATH" not in env and zoneinfo is not None:
        # the search path this interpreter found in sysconfig's build data: given to the serving
        # one, its zoneinfo (imported by pydantic, used by no service) does not load sysconfig
        env["PYTHONTZPATH"], env[TZPATH_ENV] = os.pathsep.join(zoneinfo.TZPATH), "1"
    argv = [sys.executable, "-m", __name__, *shown_args]
    os.execve(sys.executable, argv, env)  # noqa: S606  # this Python, no shell


def serve(handover: Handover) -> None:
    """Serve the handover's components until SIGTERM or SIGINT; motors stop on every path."""
    from umlbot.services.host import ServiceGroup

    group = ServiceGroup(
        handover.kinds,
        Deployment.from_handover(handover.deployment),
        handover.broker,
        handover.robot,
        handover.driver,
        components=handover.components,
        connect_timeout_s=handover.connect_timeout_s,
    )
    run(group)


def run(group: Any) -> None:
    """Start `group` (a `ServiceGroup`) and serve until a signal; stop it on every path."""
    with StopSignals() as signals:
        try:
            group.start()  # a signal meanwhile interrupts the start (exit 130)
            signals.running()
            group.wait(signals.stop)
        finally:
            group.stop()  # motors stop here on every path: signal, error, KeyboardInterrupt


def main() -> None:
    """`python -m umlbot.services.serve`, run by `umlbot service` only."""
    if os.environ.pop(TZPATH_ENV, None):  # zoneinfo has read it (pydantic imported it above)
        os.environ.pop("PYTHONTZPATH", None)
    text = os.environ.pop(HANDOVER_ENV, None)
    if text is None:
        sys.stderr.write(f"error: {__name__} is started by `umlbot service`, not by hand\n")
        sys.exit(2)
    try:
        handover = decode(text)
        configure_logging(handover.log_level, handover.log_json)
        serve(handover)
    except UmlbotError as exc:
        sys.stderr.write(f"error: {exc}\n")
        sys.exit(1)
    except OSError as exc:
        where = f"{exc.filename}: " if exc.filename else ""
        sys.stderr.write(f"error: {where}{exc.strerror or exc}\n")
        sys.exit(1)
    except KeyboardInterrupt:  # a signal while it starts: what `umlbot` (click's Abort) says
        sys.stderr.write("aborted\n")
        sys.exit(130)
