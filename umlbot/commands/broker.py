"""`umlbot broker`: run the embedded MQTT broker (amqtt) until SIGINT or SIGTERM."""

from __future__ import annotations

import signal
import threading
from pathlib import Path
from types import FrameType

import click

from umlbot.base.logs import get_logger

log = get_logger(__name__)


@click.command(name="broker")
@click.option("--bind", "host", default="127.0.0.1", show_default=True,
              help="Address to listen on (0.0.0.0 for every interface).")
@click.option("--port", default=1883, show_default=True, type=click.IntRange(0, 65535),
              help="TCP port to listen on.")
@click.option("--passwd", "passwd_file", type=click.Path(dir_okay=False, path_type=Path), default=None,
              help="amqtt password file (user:argon2-hash lines); anonymous clients are then refused.")
@click.option("--acl", "acl_file", type=click.Path(dir_okay=False, path_type=Path), default=None,
              help="YAML file with per-user topic filters: keys `acl` (subscribe) and `publish_acl`.")
@click.option("--max-retained", "max_retained", default=256 * 1024, show_default=True,
              type=click.IntRange(1, None), metavar="BYTES",
              help="A retained message larger than this is delivered but not retained (logged).")
@click.option("--hash-password", "hash_user", metavar="USER", default=None,
              help="Print a password-file line `USER:<argon2 hash>` (password from the prompt), then exit.")
def command(
    host: str, port: int, passwd_file: Path | None, acl_file: Path | None, max_retained: int,
    hash_user: str | None,
) -> None:
    """Run the embedded MQTT broker (amqtt, MQTT 3.1.1) until Ctrl-C or SIGTERM.

    It listens on loopback only, unless --bind says otherwise; reachable from other hosts without
    --passwd and --acl, it says so on stderr (anyone there could drive the motors).
    """
    from umlbot.services.bus import BrokerLimits, EmbeddedBroker, check_user_name, password_line

    if hash_user is not None:
        check_user_name(hash_user)  # before asking for the password
        password = click.prompt(f"password for {hash_user}", hide_input=True, confirmation_prompt=True,
                                err=True)
        click.echo(password_line(hash_user, password))
        return

    broker = EmbeddedBroker(host=host, port=port, passwd_file=passwd_file, acl=acl_file,
                            limits=BrokerLimits(max_retained_bytes=max_retained))
    stop = threading.Event()

    def on_signal(signum: int, frame: FrameType | None) -> None:
        log.info("broker_signal", signal=signal.Signals(signum).name)
        stop.set()

    previous = {sig: signal.signal(sig, on_signal) for sig in (signal.SIGINT, signal.SIGTERM)}
    try:
        broker.start()
        addresses = ", ".join(broker.listening_on) or f"{host}:{broker.port}"
        local = "" if broker.url.endswith(tuple(broker.listening_on)) else f"; on this machine {broker.url}"
        click.echo(f"umlbot broker listening on {addresses}{local}", err=True)
        warning = broker.exposure()
        if warning is not None:
            log.warning("broker_exposed", host=host, port=broker.port, users=passwd_file is not None,
                        acl=acl_file is not None)
            click.secho(f"WARNING: {warning}", err=True, fg="yellow", bold=True)
        while not stop.wait(1.0):
            pass
    finally:
        broker.stop()
        for sig, handler in previous.items():
            signal.signal(sig, handler)
