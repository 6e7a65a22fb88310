"""`umlbot record -o FILE.mcap`: record a running robot from outside, as a rosbag2 MCAP file.

Subscribes to `umlbot/<robot>/#` with a read-only connection and writes what it sees (the trace,
calls with their replies and latency, component status and state, the orchestrator's status,
signals), stamped with wall time, until Ctrl-C, SIGTERM, `--duration`, or with `--until-stopped`
the robot's orchestrator stopping. `umlbot run --record` runs it as its own process.
"""

from __future__ import annotations

import os
import time
from pathlib import Path

import click

from umlbot.base.stopsignals import StopSignals
from umlbot.commands.options import seconds


@click.command(name="record")
@click.option("--robot", default=lambda: os.environ.get("UMLBOT_ROBOT") or None, required=True,
              show_default="$UMLBOT_ROBOT", help="Robot id to record (topics umlbot/<robot>/#).")
@click.option("--broker", "broker_url", default=None, metavar="URL",
              help="Broker URL, e.g. mqtt://user:pass@host:1883 "
              "(default: $UMLBOT_BROKER or mqtt://127.0.0.1:1883).")
@click.option("--ca-file", type=click.Path(dir_okay=False, path_type=Path), default=None,
              help="CA certificate file for mqtts:// brokers.")
@click.option("-o", "--output", type=click.Path(dir_okay=False, path_type=Path), required=True,
              metavar="FILE.mcap", help="The recording to write (replaced when it exists).")
@click.option("--duration", type=seconds(), default=None,
              help="Stop after this many seconds (default: until Ctrl-C or SIGTERM).")
@click.option("--until-stopped", is_flag=True,
              help="Also stop when the robot's orchestrator, seen running, stops (or fails).")
@click.option("--connect-timeout", default=5.0, show_default=True, type=seconds(0.1),
              help="Seconds to wait for the broker connection.")
@click.option("--model", "model_name", default=None, hidden=True, help="The model's name, for the metadata.")
def command(robot: str, broker_url: str | None, ca_file: Path | None, output: Path,
            duration: float | None, until_stopped: bool, connect_timeout: float,
            model_name: str | None) -> None:
    """Record ROBOT's traffic to a rosbag2-compatible MCAP file (docs/recording.md)."""
    from umlbot.base.topics import check_name
    from umlbot.commands.recording import report
    from umlbot.record import open_file_recorder
    from umlbot.services.bus import BrokerSettings, resolve_broker_url

    check_name("robot id", robot)
    settings = BrokerSettings.from_url(resolve_broker_url(broker_url), ca_file=ca_file)
    with StopSignals() as signals:
        recorder = open_file_recorder(output, robot, "wall", time.time, model_name)
        try:
            try:
                recorder.listen(settings, trace=True, timeout=connect_timeout)
            except BaseException:
                recorder.close()
                output.unlink(missing_ok=True)  # nothing was recorded: no file
                raise
            signals.running()
            click.echo(f"recording umlbot/{robot}/# from {settings.url} to {output} (Ctrl-C ends it)",
                       err=True)
            deadline = None if duration is None else time.monotonic() + duration
            while not signals.stop.wait(0.05):
                if until_stopped and recorder.orchestrator_ended.is_set():
                    break
                if deadline is not None and time.monotonic() >= deadline:
                    break
        finally:
            stats = recorder.close()
    click.echo(f"{output}: {stats.messages} messages", err=True)
    report(output, stats, False)
