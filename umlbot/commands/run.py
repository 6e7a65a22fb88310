"""`umlbot run COMPILED`: the orchestrator, executing a compiled model against the robot's services.

Exit status: 0 the model ended or termination was requested (SIGINT/SIGTERM, an exit request on
`umlbot/<robot>/orchestrator/exit`); 1 fail-safe stop (a call timed out or got an error reply, a
used component went offline, the broker connection was lost) or the run could not start
(components not online, broker unreachable, unreadable compiled model); 2 bad command line.
"""

from __future__ import annotations

import os
from pathlib import Path

import click

from umlbot.commands.options import Number, seconds


class RunFailed(click.ClickException):
    """The run ended with a fail-safe stop: one line on stderr, exit status 1."""

    exit_code = 1

    def show(self, file: object = None) -> None:
        click.echo(f"error: {self.format_message()}", err=True)


@click.command(name="run")
@click.argument("compiled", type=click.Path(exists=True, dir_okay=False, path_type=Path))
@click.option("--broker", "broker_url", default=None, metavar="URL",
              help="Broker URL, e.g. mqtt://user:pass@host:1883 "
              "(default: $UMLBOT_BROKER or mqtt://127.0.0.1:1883).")
@click.option("--ca-file", type=click.Path(dir_okay=False, path_type=Path), default=None,
              help="CA certificate file for mqtts:// brokers.")
@click.option("--robot", metavar="ID", default=lambda: os.environ.get("UMLBOT_ROBOT") or None,
              show_default="$UMLBOT_ROBOT or the model's name",
              help="Robot id (the topic base is umlbot/<robot>/).")
@click.option("--call-timeout", "call_timeout_s", type=seconds(0.001),
              default=None, help="Seconds a feature call may take (default: the model's call_timeout_s).")
@click.option("--trace", "trace_file", type=click.Path(dir_okay=False, path_type=Path), default=None,
              metavar="FILE", help="Also write every trace event to FILE (JSON lines).")
@click.option("--no-trace", is_flag=True, help="Do not publish trace events on MQTT.")
@click.option("--grace", "grace_s", type=seconds(), default=None,
              help="Seconds the lanes get to finish after an exit request [default: 2].")
@click.option("--startup-timeout", "startup_timeout_s", type=seconds(), default=None,
              help="Seconds to wait for the used components to be online [default: 10].")
@click.option("--record", "record_file", type=click.Path(dir_okay=False, path_type=Path), default=None,
              metavar="FILE.mcap", help="Record the run as a rosbag2-compatible MCAP file (wall time): "
              "trace, calls, states, signals (docs/recording.md).")
@click.option("--speed", type=Number(min=0, max=1000, min_open=True), default=1.0, hidden=True,
              help="Clock speed factor (for the simulator).")
def command(
    compiled: Path,
    broker_url: str | None,
    ca_file: Path | None,
    robot: str | None,
    call_timeout_s: float | None,
    trace_file: Path | None,
    no_trace: bool,
    grace_s: float | None,
    startup_timeout_s: float | None,
    speed: float,
    record_file: Path | None,
) -> None:
    """Run the orchestrator on COMPILED (a file written by `umlbot compile`).

    Waits for every component the model uses to be online, stops every actuator, runs every
    component swimlane until they end or SIGINT/SIGTERM arrives, and stops every actuator again.
    """
    from umlbot.base.clock import Clock
    from umlbot.compiler.compiled import load_compiled
    from umlbot.services.bus import BrokerSettings, resolve_broker_url
    from umlbot.services.orchestrator import DEFAULT_GRACE_S, DEFAULT_STARTUP_TIMEOUT_S, EXIT_OK, Orchestrator

    model = load_compiled(compiled)
    settings = BrokerSettings.from_url(resolve_broker_url(broker_url), ca_file=ca_file)
    recorder = None
    if record_file is not None:
        if no_trace:
            raise click.UsageError("--record records the trace from MQTT: leave out --no-trace")
        from umlbot.base import rosmsg
        from umlbot.record import RecorderProcess, check_writable

        rosmsg.require("rosbags.typesys", "record", "Recordings (--record)")  # before anything runs
        check_writable(record_file)
        recorder = RecorderProcess(resolve_broker_url(broker_url), robot or model.name, record_file,
                                   ca_file, model.name)
    orchestrator = Orchestrator(
        model,
        settings,
        robot=robot,
        clock=Clock(speed),
        call_timeout_s=call_timeout_s,
        trace=not no_trace,
        trace_file=trace_file,
        grace_s=DEFAULT_GRACE_S if grace_s is None else grace_s,
        startup_timeout_s=DEFAULT_STARTUP_TIMEOUT_S if startup_timeout_s is None else startup_timeout_s,
    )
    try:
        if recorder is not None:
            recorder.start()  # subscribed before the orchestrator says anything
        code = orchestrator.run_sync()
    finally:
        if recorder is not None:
            recorder.stop()
    if code != EXIT_OK:
        raise RunFailed(f"fail-safe stop: {orchestrator.failure}")
