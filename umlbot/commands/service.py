"""`umlbot service KIND --deploy FILE`: run one hardware service (motor, sonar, servo, gpio or a
plugin's service kind).

Serves every component of that kind in the deployment until SIGTERM or SIGINT; on every exit
path (signal, error, broker loss) the motors are stopped before the process ends. KIND `all`
serves every kind the deployment uses in this one process (one unit on a small board).

`--safe-stop` serves nothing: it puts the components' hardware in its safe state (motors: pins
low) and exits, without a broker; the systemd unit runs it after every end of the service
(`ExecStopPost=`), also after SIGKILL or a watchdog kill, when the service could not do it itself.
"""

from __future__ import annotations

import os
import sys
from pathlib import Path

import click

from umlbot.commands.options import seconds


def resolve_robot(cli_value: str | None, deployment_robot: str | None) -> str:
    """Robot id: `--robot`, else `UMLBOT_ROBOT`, else the deployment's `robot`, else `car`."""
    return cli_value or os.environ.get("UMLBOT_ROBOT") or deployment_robot or "car"


def _known_kind(ctx: click.Context, param: click.Parameter, kind: str) -> str:
    # Checked when the command runs, not when it is imported: the library (built-ins and
    # plugins) is read only then, after logging is set up.
    from umlbot.base.catalog import service_kinds

    if kind != "all" and kind not in service_kinds():
        known = ", ".join(map(repr, [*service_kinds(), "all"]))
        raise click.BadParameter(f"{kind!r} is not one of {known}.")
    return kind


@click.command(name="service")
@click.argument("kind", callback=_known_kind)
@click.option("--deploy", "deploy_file", required=True, metavar="FILE",
              type=click.Path(dir_okay=False, path_type=Path),
              help="Deployment file (plain `Component=impl` lines or YAML).")
@click.option("--driver", default=None, metavar="NAME",
              help="Driver for every component: auto, lgpio, pigpio, mock, sim or a plugin's "
              "(default: the deployment's).")
@click.option("--component", "components", multiple=True, metavar="NAME",
              help="Serve only this component (repeatable; default: all of this kind, or of every kind).")
@click.option("--broker", "broker_url", default=None, metavar="URL",
              help="Broker URL, e.g. mqtt://user:pass@host:1883 "
              "(default: $UMLBOT_BROKER or mqtt://127.0.0.1:1883).")
@click.option("--ca-file", type=click.Path(dir_okay=False, path_type=Path), default=None,
              help="CA certificate file for mqtts:// brokers.")
@click.option("--robot", default=None, metavar="ID",
              help="Robot id (default: $UMLBOT_ROBOT, the deployment's robot, or car).")
@click.option("--connect-timeout", default=10.0, show_default=True, type=seconds(0.1),
              help="Seconds to wait for the broker at start-up.")
@click.option("--safe-stop", is_flag=True,
              help="Serve nothing: put the components' hardware in its safe state (motors: pins low) "
              "and exit; no broker needed (the systemd unit's ExecStopPost).")
def command(
    kind: str,
    deploy_file: Path,
    driver: str | None,
    components: tuple[str, ...],
    broker_url: str | None,
    ca_file: Path | None,
    robot: str | None,
    connect_timeout: float,
    safe_stop: bool,
) -> None:
    """Run one hardware service (or `all` of them) for the components the deployment gives it."""
    from umlbot.base.catalog import service_kinds
    from umlbot.base.deployment import load_deployment
    from umlbot.base.library import ServiceKind
    from umlbot.services.bus import BrokerSettings, resolve_broker_url
    from umlbot.services.host import ServiceGroup

    kinds: tuple[ServiceKind, ...] = tuple(service_kinds()) if kind == "all" else (kind,)
    deployment = load_deployment(deploy_file)
    settings = BrokerSettings.from_url(resolve_broker_url(broker_url), ca_file=ca_file)
    group = ServiceGroup(
        kinds,
        deployment,
        settings,
        resolve_robot(robot, deployment.robot),
        driver,
        components=list(components) or None,
        connect_timeout_s=connect_timeout,
    )
    if safe_stop:
        group.safe_stop_hardware()  # a DriverError is the usual one line and exit 1
        return
    from umlbot.services import serve

    root = click.get_current_context().find_root()
    handover = serve.Handover(
        kinds=kinds, deployment=deployment.handover(), broker=settings,
        robot=resolve_robot(robot, deployment.robot), driver=driver, components=list(components) or None,
        connect_timeout_s=connect_timeout, log_level=root.params.get("log_level"),
        log_json=root.params.get("log_json"),
    )
    # the same process goes on without the command line's code (click, PyYAML): serve.py
    serve.replace_process(handover, ["umlbot", *sys.argv[1:]])
    serve.run(group)  # only when the handover is too long for the environment
