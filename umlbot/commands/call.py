"""`umlbot call Component.feature ARGS…`: one request from the command line, the reply as JSON.

Exit codes: 0 the call succeeded; 1 the service answered with an error reply (stderr shows
`code: message`); 2 bad command line; 3 no reply within `--timeout`; 4 the broker could not be
reached (or the connection dropped during the call); 5 the broker refused the login (a wrong user
or password: at once, no retrying) or the request or the reply subscription (its ACL), which
only MQTT 5 reports (the default; `?protocol=3.1.1` and 3.1.1-only brokers, such as the
embedded one, do not).

The request goes out at QoS 1, so that the broker's acknowledgement can carry that refusal. Over
MQTT 3.1.1 a broker drops a publish its ACL refuses without a word: on a broker with users the
time-out message says that this may be why.
"""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Any

import click

from umlbot.commands.options import seconds

EXIT_OK = 0
EXIT_ERROR_REPLY = 1
EXIT_USAGE = 2
EXIT_TIMEOUT = 3
EXIT_NOT_CONNECTED = 4
EXIT_REFUSED = 5


class CallFailed(click.ClickException):
    """A failed call: one line on stderr; subclasses set the exit code."""

    def show(self, file: Any = None) -> None:
        click.echo(self.format_message(), err=True)


class ErrorReplyFailure(CallFailed):
    exit_code = EXIT_ERROR_REPLY


class TimeoutFailure(CallFailed):
    exit_code = EXIT_TIMEOUT


class NotConnectedFailure(CallFailed):
    exit_code = EXIT_NOT_CONNECTED


class RefusedFailure(CallFailed):
    exit_code = EXIT_REFUSED


def timeout_hint(component: str, robot: str, username: str | None, protocol: str) -> str:
    """What a time-out may mean: no such service, or (3.1.1 with a user) the ACL dropping it."""
    hint = f"is the {component} service running for robot {robot!r}?"
    if username is not None and protocol != "5":
        hint += (f" On a broker with users the ACL may also have dropped the request of user "
                 f"{username!r} without a word (this connection speaks MQTT 3.1.1, which has no "
                 f"error for it; over MQTT 5, the default where the broker speaks it, Mosquitto "
                 f"says why)")
    return hint


def parse_arg(text: str) -> Any:
    """A command-line argument as JSON when it parses (`60`, `true`, `[1,2]`), else the string.

    Parsed by the loader that reads the wire (`umlbot.base.files.loads_json`), strictly: what parses but
    cannot be sent as JSON (NaN, Infinity, 1e400) or what the decoder refuses (nesting too deep, an
    integer too long) is a bad command line (exit 2), not a string and not a traceback.
    """
    from umlbot.base.files import loads_json

    try:
        return loads_json(text, finite=True)
    except json.JSONDecodeError:
        return text
    except ValueError as exc:
        raise click.BadParameter(f"{_shorten(text)}: {exc}", param_hint="ARGS") from None


def _shorten(text: str, limit: int = 40) -> str:
    return repr(text if len(text) <= limit else text[:limit] + "…")


def parse_target(target: str) -> tuple[str, str]:
    """`Component.feature` -> (component, feature), each one MQTT topic level (as robot ids)."""
    from umlbot.base.errors import ConfigError
    from umlbot.base.topics import check_name

    component, dot, feature = target.partition(".")
    if not dot or not component or not feature or "." in feature:
        raise click.BadParameter(f"expected Component.feature, got {target!r}", param_hint="TARGET")
    try:
        check_name("component", component)
        check_name("feature", feature)
    except ConfigError as exc:
        raise click.BadParameter(str(exc), param_hint="TARGET") from None
    return component, feature


@click.command(name="call", context_settings={"ignore_unknown_options": True})
@click.argument("target")
@click.argument("args", nargs=-1, type=click.UNPROCESSED)
@click.option("--robot", default=lambda: os.environ.get("UMLBOT_ROBOT") or "car",
              show_default="$UMLBOT_ROBOT or car",
              help="Robot id (the topic base is umlbot/<robot>/).")
@click.option("--timeout", default=2.0, show_default=True, type=seconds(0.01),
              help="Seconds to wait for the reply.")
@click.option("--broker", "broker_url", default=None, metavar="URL",
              help="Broker URL, e.g. mqtt://user:pass@host:1883 "
              "(default: $UMLBOT_BROKER or mqtt://127.0.0.1:1883).")
@click.option("--ca-file", type=click.Path(dir_okay=False, path_type=Path), default=None,
              help="CA certificate file for mqtts:// brokers.")
@click.option("--connect-timeout", default=3.0, show_default=True, type=seconds(0.1),
              help="Seconds to wait for the broker connection.")
def command(
    target: str,
    args: tuple[str, ...],
    robot: str,
    timeout: float,
    broker_url: str | None,
    ca_file: Path | None,
    connect_timeout: float,
) -> None:
    """Call TARGET (Component.feature) with ARGS and print the reply as JSON.

    Each ARG is JSON when it parses (60, true, "text", [1,2]) and a string otherwise; NaN and
    Infinity are refused (they are not JSON).
    Exit status: 0 ok, 1 error reply, 3 time-out, 4 broker not reachable, 5 refused by the
    broker: the login (user or password), or the request (MQTT 5 only: over 3.1.1 a refused
    request ends as a time-out).

    Example: umlbot call LeftActuator.dutycycle 60
    """
    from umlbot.base.errors import BrokerRefused, CallTimeout, LoginRefused, NotConnected, RemoteError
    from umlbot.services.bus import BrokerSettings, BusClient, resolve_broker_url

    component, feature = parse_target(target)
    values = [parse_arg(a) for a in args]
    settings = BrokerSettings.from_url(resolve_broker_url(broker_url), ca_file=ca_file)
    client = BusClient(settings, robot, role="cli")
    try:
        try:
            client.start(connect_timeout)
            refused = client.connection.refused_subscriptions.get(client.reply_topic)
            if refused is not None:
                raise BrokerRefused(f"the subscription to the reply topic {client.reply_topic}", refused)
            value = client.call(component, feature, *values, timeout=timeout, acknowledged=True)
        except RemoteError as exc:
            click.echo(json.dumps({"ok": False, "error": {"code": exc.code, "message": exc.message}}))
            raise ErrorReplyFailure(f"{exc.code}: {exc.message}") from None
        except CallTimeout as exc:
            hint = timeout_hint(component, robot, settings.username, client.connection.protocol)
            raise TimeoutFailure(f"timeout: {exc} ({hint})") from None
        except LoginRefused as exc:
            raise RefusedFailure(f"refused: {exc}") from None
        except BrokerRefused as exc:
            user = f" for user {settings.username!r}" if settings.username else ""
            raise RefusedFailure(f"refused: {exc}{user}") from None
        except NotConnected as exc:
            raise NotConnectedFailure(f"not_connected: {exc}") from None
        click.echo(json.dumps({"ok": True, "value": value}, ensure_ascii=False))
    finally:
        client.close()
