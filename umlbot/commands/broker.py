"""`umlbot broker`: run the embedded MQTT broker (amqtt) until SIGINT or SIGTERM."""

from __future__ import annotations

import signal
import threading
from pathlib import Path
from types import FrameType

import click

from umlbot.logs import get_logger

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
@click.option("--hash-password", "hash_user", metavar="USER", default=None,
              help="Print a password-file line `USER:<argon2 hash>` (password from the prompt), then exit.")
def command(
    host: str, port: int, passwd_file: Path | None, acl_file: Path | None, hash_user: str | None
) -> None:
    """Run the embedded MQTT broker (amqtt, MQTT 3.1.1) until Ctrl-C or SIGTERM.

    It listens on loopback only, unless --bind says otherwise.
    """
    from services.bus.broker import EmbeddedBroker, check_user_name, password_line

    if hash_user is not None:
        check_user_name(hash_user)  # before asking for the password
        password = click.prompt(f"password for {hash_user}", hide_input=True, confirmation_prompt=True,
                                err=True)
        click.echo(password_line(hash_user, password))
        return

    broker = EmbeddedBroker(host=host, port=port, passwd_file=passwd_file, acl=acl_file)
    stop = threading.Event()

    def on_signal(signum: int, frame: FrameType | None) -> None:
        log.info("broker_signal", signal=signal.Signals(signum).name)
        stop.set()

    previous = {sig: signal.signal(sig, on_signal) for sig in (signal.SIGINT, signal.SIGTERM)}
    try:
        broker.start()
        click.echo(f"umlbot broker listening on {broker.url}", err=True)
        while not stop.wait(1.0):
            pass
    finally:
        broker.stop()
        for sig, handler in previous.items():
            signal.signal(sig, handler)
