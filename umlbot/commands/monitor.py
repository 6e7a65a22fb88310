"""`umlbot monitor`: a live view of a robot's traffic, JSON lines for piping, or a trace replay."""

from __future__ import annotations

import contextlib
import os
import sys
import threading
import time
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING

import click

from umlbot.base.stopsignals import StopSignals
from umlbot.commands.options import Number, seconds

if TYPE_CHECKING:
    from umlbot.monitor import MonitorEvent, MonitorState

Sink = Callable[["MonitorEvent"], None]

REFRESH_S = 0.25


@click.command(name="monitor")
@click.option("--robot", default=lambda: os.environ.get("UMLBOT_ROBOT") or None,
              show_default="$UMLBOT_ROBOT, else every robot",
              help="Robot id to watch (topics umlbot/<robot>/#); '*' for every robot on the broker (a fleet "
              "hub), or a comma-separated list (car1,car2).")
@click.option("--broker", "broker_url", default=None, metavar="URL",
              help="Broker URL, e.g. mqtt://user:pass@host:1883 "
              "(default: $UMLBOT_BROKER or mqtt://127.0.0.1:1883).")
@click.option("--ca-file", type=click.Path(dir_okay=False, path_type=Path), default=None,
              help="CA certificate file for mqtts:// brokers.")
@click.option("--json", "as_json", is_flag=True, help="Print one JSON line per event instead of the view.")
@click.option("--replay", "replay_file", type=click.Path(dir_okay=False, path_type=Path), default=None,
              help="Play a recorded trace (umlbot run --trace FILE) instead of watching the broker.")
@click.option("--speed", type=Number(min=0, max=1000), default=None,
              help="Replay speed: 1 = recorded pace, 0 = no waiting "
              "(default: 1 for the view, 0 with --json).")
@click.option("--duration", type=seconds(), default=None,
              help="Stop after this many seconds (default: until Ctrl-C or SIGTERM).")
@click.option("--call-timeout", type=seconds(0.1), default=None,
              show_default="the time-out the orchestrator's status says, else 5",
              help="Report a call without a reply after this many seconds.")
@click.option("--connect-timeout", default=5.0, show_default=True, type=seconds(0.1),
              help="Seconds to wait for the broker connection.")
def command(
    robot: str | None,
    broker_url: str | None,
    ca_file: Path | None,
    as_json: bool,
    replay_file: Path | None,
    speed: float | None,
    duration: float | None,
    call_timeout: float | None,
    connect_timeout: float,
) -> None:
    """Watch the robot: availability, calls with their latency, the node each lane runs.

    With --json every event is one JSON line on stdout (type: availability, call, state, signal,
    trace, orchestrator, exit). With --replay FILE a recorded trace is played instead.
    """
    from umlbot.monitor import MonitorState

    out_lock = threading.Lock()

    def print_line(event: MonitorEvent) -> None:
        with out_lock:
            sys.stdout.write(event.line() + "\n")
            sys.stdout.flush()

    state = MonitorState(call_timeout_s=call_timeout)
    with StopSignals() as signals:
        if replay_file is not None:
            if robot and ("," in robot or "*" in robot):
                raise click.UsageError("--replay plays one robot's trace: give --robot one id (or none)")
            _check_trace(replay_file)  # before the view is drawn: a bad file is only its error line
            signals.running()
            # a trace file does not say whose it is: without --robot its events name no robot
            sink: Sink = print_line if robot else _without_robot(out_lock)
            _run_replay(replay_file, state, robot or "", as_json, sink, speed, signals.stop)
        else:
            _run_live(state, robot, broker_url, ca_file, as_json, print_line, duration, connect_timeout,
                      signals)


def _check_trace(path: Path) -> None:
    """Read the whole trace once: an unreadable file, a bad line anywhere or no event at all
    raises ConfigError (exit 1) before anything is shown."""
    from umlbot.base.errors import ConfigError
    from umlbot.monitor import read_trace

    if sum(1 for _ in read_trace(path)) == 0:  # every line read: a bad one is found now
        raise ConfigError(f"{path}: no trace events (an empty trace file; record one with "
                          "umlbot run --trace FILE)")


def _without_robot(out_lock: threading.Lock) -> Sink:
    """A sink that prints events without their `robot` (unknown in a replay without --robot)."""
    import json

    def print_event(event: MonitorEvent) -> None:
        data = event.model_dump(mode="json", exclude_none=True)
        data.pop("robot", None)
        with out_lock:
            sys.stdout.write(json.dumps(data, separators=(",", ":"), ensure_ascii=False) + "\n")
            sys.stdout.flush()

    return print_event


class _Stopped(Exception):
    """The user stopped a replay."""


def _run_replay(path: Path, state: MonitorState, robot: str, as_json: bool, print_line: Sink,
                speed: float | None, stop: threading.Event) -> None:
    from rich.console import Console
    from rich.live import Live

    from umlbot.monitor import render, replay

    pace = speed if speed is not None else (0.0 if as_json else 1.0)

    def sleep(seconds: float) -> None:
        if stop.wait(seconds):
            raise _Stopped

    if as_json:
        with contextlib.suppress(_Stopped):
            replay(path, state, robot, print_line, pace, sleep)
        return
    console = Console()
    with Live(render(state, title="umlbot monitor (replay)"), console=console, auto_refresh=False) as live:
        last = 0.0

        def redraw(event: MonitorEvent) -> None:
            nonlocal last
            now = time.monotonic()
            if now - last >= REFRESH_S:
                live.update(render(state, now=event.time, title="umlbot monitor (replay)"), refresh=True)
                last = now

        try:
            end = replay(path, state, robot, redraw, pace, sleep)
        except _Stopped:
            end = 0
        final = max((lane.at for lane in state.lanes.values()), default=time.time())
        live.update(render(state, now=final, title=f"umlbot monitor (replay, {end} events)"), refresh=True)


def _run_live(state: MonitorState, robot: str | None, broker_url: str | None, ca_file: Path | None,
              as_json: bool, print_line: Sink, duration: float | None, connect_timeout: float,
              signals: StopSignals) -> None:
    from rich.console import Console
    from rich.live import Live

    from umlbot.monitor import LiveMonitor, render
    from umlbot.services.bus import BrokerSettings, resolve_broker_url

    settings = BrokerSettings.from_url(resolve_broker_url(broker_url), ca_file=ca_file)

    def ignore(event: MonitorEvent) -> None:
        pass

    sink = print_line if as_json else ignore
    monitor = LiveMonitor(settings, robot, sink, state)
    deadline = None if duration is None else time.monotonic() + duration
    stop = signals.stop
    try:
        monitor.start(connect_timeout)  # a signal meanwhile interrupts the start (exit 130)
        signals.running()
        if as_json:
            while not stop.wait(REFRESH_S) and (deadline is None or time.monotonic() < deadline):
                monitor.tick()
            return
        with Live(console=Console(), auto_refresh=False) as live:
            while deadline is None or time.monotonic() < deadline:
                monitor.tick()
                with monitor.lock:
                    frame = render(state)
                live.update(frame, refresh=True)
                if stop.wait(REFRESH_S):
                    break
    finally:
        monitor.close()
