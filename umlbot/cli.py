"""The `umlbot` command line: a thin face over the compiler, the services and the simulator.

Each command lives in its own module `umlbot/commands/<name>.py` exposing `command`, loaded only
when it is used so that `umlbot call` starts fast on a Raspberry Pi.

`--log-level` and `--log-json/--no-log-json` are the group's options and every command's too:
`umlbot --log-level DEBUG run X` and `umlbot run X --log-level DEBUG` are the same (given in both
places, the one after the command name wins). Logging is configured once, just before the command
runs, from what both places said.
"""

from __future__ import annotations

import functools
import importlib
import sys
from typing import Any

import click

from umlbot import __version__
from umlbot.base.errors import UmlbotError
from umlbot.base.logs import configure_logging

#: command name -> one-line help; the module `umlbot.commands.<name>` defines `command`.
COMMANDS: dict[str, str] = {
    "check": "Validate a model; print every problem as file:line:col.",
    "compile": "Compile a model into a compiled model file.",
    "render": "Draw the model's diagrams as Mermaid, PlantUML, DOT and SVG.",
    "broker": "Run the embedded MQTT broker (amqtt).",
    "service": "Run one hardware service (motor, sonar, servo, gpio).",
    "run": "Run the orchestrator on a compiled model.",
    "sim": "Run the whole robot in the 2D simulator.",
    "call": "Call one component feature over MQTT and print the reply.",
    "monitor": "Watch the robot's traffic live.",
    "studio": "Serve the browser studio: diagrams, the running robot live, trace replay.",
    "plugins": "List the installed component and driver plugins (entry points).",
    "calibrate": "Calibrate a sensor: 'calibrate stereo' for a stereo camera (chessboard pairs).",
    "ros2-bridge": "Show the robot to ROS 2: status, states, trace; features as a ROS 2 service.",
    "record": "Record a running robot as a rosbag2-compatible MCAP file.",
    "generate": "Generate the model's swimlanes as a C++17 CMake project (`generate cpp`).",
}


class LazyGroup(click.Group):
    """A group whose subcommands are imported on first use."""

    def list_commands(self, ctx: click.Context) -> list[str]:
        return sorted(COMMANDS)

    def get_command(self, ctx: click.Context, cmd_name: str) -> click.Command | None:
        if cmd_name not in COMMANDS:
            return None
        module = importlib.import_module(f"umlbot.commands.{cmd_name.replace('-', '_')}")
        command: click.Command = module.command
        return with_log_options(command)

    def format_commands(self, ctx: click.Context, formatter: click.HelpFormatter) -> None:
        with formatter.section("Commands"):
            formatter.write_dl([(name, COMMANDS[name]) for name in self.list_commands(ctx)])


LOG_LEVELS = ("DEBUG", "INFO", "WARNING", "ERROR")
#: commands a person runs and reads: their logs are plain sentences on any stderr, JSON only when
#: asked for (--log-json); the services' and the orchestrator's stay JSON when not on a terminal.
PERSON_COMMANDS = frozenset({"check", "compile", "render", "sim", "studio"})


def _log_level_option(**kwargs: Any) -> click.Option:
    return click.Option(["--log-level"], default=None, metavar="LEVEL",
                        type=click.Choice(LOG_LEVELS, case_sensitive=False),
                        help="DEBUG, INFO, WARNING or ERROR (env UMLBOT_LOG_LEVEL).", **kwargs)


def _log_json_option(**kwargs: Any) -> click.Option:
    return click.Option(["--log-json/--no-log-json"], default=None,
                        help="JSON log lines (default: when not a terminal, except for check, compile, "
                        "render, sim and studio: plain sentences; env UMLBOT_LOG_JSON=1).", **kwargs)


def _remember(ctx: click.Context, param: click.Parameter, value: Any) -> None:
    """A log option given after the command name: it goes where the group's own value is kept
    (the root context's params, where `umlbot sim` also looks), overriding it."""
    if value is not None and param.name is not None:
        ctx.find_root().params[param.name] = value


def with_log_options(command: click.Command) -> click.Command:
    """`command` accepting the group's log options too, and configuring logging before it runs
    (once per command object: the commands are module-level singletons)."""
    if getattr(command, "_umlbot_log_options", False):
        return command
    command.params += [_log_level_option(expose_value=False, callback=_remember),
                       _log_json_option(expose_value=False, callback=_remember)]
    original = command.callback
    if original is not None:
        @functools.wraps(original)
        def run(*args: Any, **kwargs: Any) -> Any:
            root = click.get_current_context().find_root()
            configure_logging(root.params.get("log_level"), root.params.get("log_json"),
                              person=command.name in PERSON_COMMANDS)
            return original(*args, **kwargs)

        command.callback = run
    command._umlbot_log_options = True  # type: ignore[attr-defined]
    return command


@click.group(cls=LazyGroup, context_settings={"help_option_names": ["-h", "--help"]})
@click.version_option(__version__, prog_name="umlbot")
@click.option("--log-level", default=None, metavar="LEVEL",
              type=click.Choice(LOG_LEVELS, case_sensitive=False),
              help="DEBUG, INFO, WARNING or ERROR (env UMLBOT_LOG_LEVEL); also after the command name.")
@click.option("--log-json/--no-log-json", default=None,
              help="JSON log lines (default: when not a terminal); also after the command name.")
def cli(log_level: str | None, log_json: bool | None) -> None:
    """umlbot: build a robot from UML models."""
    # logging is configured just before the command runs (`with_log_options`): the command's
    # own --log-level / --log-json, given after its name, are not parsed yet here


def main() -> None:
    """Console entry point: run the CLI; an UmlbotError or OSError becomes one line and exit 1."""
    try:
        # Non-standalone so that UmlbotError reaches us; click then returns ctx.exit() codes.
        code = cli.main(standalone_mode=False)
        if isinstance(code, int) and code != 0:
            sys.exit(code)
    except click.exceptions.Abort:
        click.echo("aborted", err=True)
        sys.exit(130)
    except click.ClickException as exc:
        exc.show()
        sys.exit(exc.exit_code)
    except click.exceptions.Exit as exc:
        sys.exit(exc.exit_code)
    except UmlbotError as exc:
        click.echo(f"error: {exc}", err=True)
        sys.exit(1)
    except OSError as exc:  # a file or folder the user named cannot be read or written
        where = f"{exc.filename}: " if exc.filename else ""
        click.echo(f"error: {where}{exc.strerror or exc}", err=True)
        sys.exit(1)
    except KeyboardInterrupt:
        sys.exit(130)
