"""`umlbot sim MODEL`: run the whole robot in the 2D simulator and report how it went."""

from __future__ import annotations

import json
import math
import os
import sys
from pathlib import Path
from typing import Any

import click

from umlbot.base.stopsignals import StopSignals
from umlbot.commands.options import Number, seconds

DEFAULT_TRACK = "s_bend"  # the bundled track, wherever umlbot is run from


@click.command(name="sim")
@click.argument("model", type=click.Path(exists=True, path_type=Path))
@click.option("--track", "track", type=click.Path(dir_okay=False, path_type=Path), default=None,
              help="Track file, or a bundled track's bare name such as corridor (no '/', no .yaml: a path "
              f"that is not there is an error) (default: the bundled {DEFAULT_TRACK}).")
@click.option("--speed", type=Number(min=0.1, max=100), default=10.0, show_default=True,
              help="Sim seconds per wall second (model sleeps and the world).")
@click.option("--broker", "broker_url", default=None, metavar="URL",
              help="Use this broker instead of starting the embedded one.")
@click.option("--port", type=click.IntRange(0, 65535), default=None,
              help="Port of the embedded broker (default 1883, or a free one when 1883 is taken; "
              "0 = any free port).")
@click.option("--timeout", "timeout_s", type=seconds(1), default=600.0, show_default=True,
              help="Give up after this many sim seconds.")
@click.option("--plot", type=click.Path(dir_okay=False, path_type=Path), default=None,
              help="Write the track, path and sonar pings to this .png, .svg or .pdf file (also the track "
              "and its problem when the track is refused).")
@click.option("--processes", is_flag=True,
              help="Run each service as its own 'umlbot service' process (as on the robot).")
@click.option("--seed", type=int, default=None, help="Seed of the sonar noise and dropped echoes.")
@click.option("--noise", "noise_cm", type=Number(min=0, max=1000), default=0.0, show_default=True,
              help="Sonar noise, standard deviation in cm.")
@click.option("--drop", "drop_percent", type=Number(0, 100), default=0.0, show_default=True,
              help="Percentage of sonar pings whose echo is lost.")
@click.option("--max-collisions", type=click.IntRange(min=1), default=1, show_default=True,
              help="Stop after this many collisions.")
@click.option("--robot", default=None, metavar="ID",
              help="Robot id in the topics (default: the model's name); with --robots the prefix of the ids.")
@click.option("--robots", type=click.IntRange(min=1), default=None, metavar="N",
              help="A fleet on this machine: N cars (robot ids <robot or model name>1..N), each with its own "
              "Mosquitto bridged to a hub Mosquitto (see docs/fleet.md).")
@click.option("--hub-port", type=click.IntRange(0, 65535), default=0, show_default=True,
              help="With --robots: the hub's port on 127.0.0.1 (0 = any free port).")
@click.option("--json", "as_json", is_flag=True, help="Print the summary as one JSON object.")
@click.option("--trace", "trace_file", type=click.Path(dir_okay=False, path_type=Path), default=None,
              metavar="FILE", help="Also write every trace event to FILE (JSON lines, sim time): "
              "replay it with 'umlbot studio --replay FILE'.")
@click.option("--studio", is_flag=True,
              help="Follow the run in umlbot studio (the page stays open after the run until Ctrl-C).")
@click.option("--studio-port", type=click.IntRange(0, 65535), default=8080, show_default=True,
              help="Port of the studio page (0 = any free port).")
@click.option("--record", "record_file", type=click.Path(dir_okay=False, path_type=Path), default=None,
              metavar="FILE.mcap", help="Record the run as a rosbag2-compatible MCAP file (sim time): "
              "trace, calls, states, signals, pose, sonar, track (docs/recording.md).")
@click.option("--foxglove", is_flag=True,
              help="Serve the run live to Foxglove (WebSocket on 127.0.0.1, its URL is printed).")
@click.option("--foxglove-port", type=click.IntRange(0, 65535), default=8765, show_default=True,
              help="Port of the Foxglove server (0 = any free port).")
@click.option("--engine", type=click.Choice(["python", "cpp"]), default="python", show_default=True,
              help="cpp: run the model's generated C++ program (`umlbot generate cpp`, built once and "
              "cached) instead of the orchestrator in this process, on the same sim clock.")
def command(model: Path, track: Path | None, speed: float, broker_url: str | None, port: int | None,
            timeout_s: float, plot: Path | None, processes: bool, seed: int | None, noise_cm: float,
            drop_percent: float, max_collisions: int, robot: str | None, robots: int | None, hub_port: int,
            as_json: bool, trace_file: Path | None, studio: bool, studio_port: int,
            record_file: Path | None, foxglove: bool, foxglove_port: int, engine: str) -> None:
    """Run MODEL on a track: embedded broker, world, services, orchestrator; exit 0 only when the
    goal was reached without a collision."""
    from umlbot.base.logs import configure_logging
    from umlbot.sim import Progress, SimOptions, find_track, run_sim

    # the progress line and the summary are the output; logs only for warnings unless asked for
    if click.get_current_context().find_root().params.get("log_level") is None and not os.environ.get(
        "UMLBOT_LOG_LEVEL"
    ):
        configure_logging("WARNING")
    if robots is not None:
        refused = [name for name, given in (("--broker", broker_url), ("--port", port), ("--plot", plot),
                                            ("--trace", trace_file), ("--studio", studio),
                                            ("--record", record_file), ("--foxglove", foxglove),
                                            ("--engine cpp", engine == "cpp")) if given]
        if refused:
            raise click.UsageError(
                f"--robots runs its own brokers and many cars: not with {', '.join(refused)}")
        sim_args = ["--track", str(find_track(track or DEFAULT_TRACK)), "--speed", str(speed),
                    "--timeout", str(timeout_s), "--noise", str(noise_cm), "--drop", str(drop_percent),
                    "--max-collisions", str(max_collisions)]
        sim_args += ["--seed", str(seed)] if seed is not None else []
        sim_args += ["--processes"] if processes else []
        _run_fleet(model, robots, robot, hub_port, sim_args, as_json)
        return
    options = SimOptions(
        model=model, track=find_track(track or DEFAULT_TRACK), speed=speed, broker_url=broker_url,
        port=port, timeout_s=timeout_s, plot=plot, processes=processes, seed=seed, sonar_noise_cm=noise_cm,
        sonar_drop=drop_percent / 100.0, max_collisions=max_collisions, trace_file=trace_file, robot=robot,
        engine=engine,
    )
    live = sys.stdout.isatty() and not as_json
    announced: list[str] = []

    signals = StopSignals()

    def show(progress: Progress) -> None:
        signals.running()  # the robot runs: from now on a signal ends the run in order
        if not announced and not as_json:
            announced.append(progress.broker_url)
            url = progress.broker_url
            click.echo(f"broker {url}  (watch it: umlbot monitor --broker {url})")
            if progress.mock_components:
                on_mock = ", ".join(f"{name} ({kind})" for name, kind in progress.mock_components.items())
                click.echo(f"no sim driver, on their mock driver: {on_mock}")
        s = progress.snapshot
        line = (f"t={s.time_s:7.1f}s  x={s.pose.x:6.2f} y={s.pose.y:6.2f} "
                f"heading={math.degrees(s.pose.heading) % 360:5.1f}°  dist={s.distance_m:5.2f} m  "
                f"actions={progress.actions:5d}  {progress.action}")
        if live:
            click.echo("\r" + line[:150].ljust(150), nl=False)
        elif not as_json:
            click.echo(line)

    follower = None
    if studio:
        from umlbot.studio.follow import SimFollower

        follower = SimFollower(model, studio_port, announce=lambda url: click.echo(
            f"umlbot studio: {url}  (follows this run)", err=as_json))
    recording = None
    if record_file is not None or foxglove:
        from umlbot.commands.recording import sim_recording

        recording = sim_recording(model, record_file, foxglove, foxglove_port,
                                  announce=lambda url: click.echo(f"foxglove: {url}", err=as_json))
    observers = [o.observe for o in (follower, recording) if o is not None]
    with signals:  # while it starts, a signal interrupts it (the run is then "interrupted")
        try:
            result = run_sim(options, show, signals.stop, observe=_all(observers),
                             trace_listener=recording.on_trace if recording is not None else None)
        except BaseException:
            if follower is not None:
                follower.close()
            if recording is not None:
                recording.close()
            raise
    if recording is not None:
        from umlbot.commands.recording import report

        report(record_file, recording.close(), as_json)
    if live:
        click.echo()
    if as_json:
        click.echo(json.dumps(result.as_dict()))
    else:
        verdict = "goal reached" if result.goal_reached else "goal NOT reached"
        click.echo(f"{result.track}: {verdict} ({result.reason})")
        click.echo(f"  collisions      {result.collisions}")
        click.echo(f"  sim time        {result.sim_s:.1f} s   wall time {result.wall_s:.1f} s")
        click.echo(f"  distance        {result.distance_m:.2f} m")
        p50 = "-" if result.action_p50_ms is None else f"{result.action_p50_ms:.2f} ms"
        p99 = "-" if result.action_p99_ms is None else f"{result.action_p99_ms:.2f} ms"
        click.echo(f"  actions         {result.actions}   latency p50 {p50}, p99 {p99}")
        if result.failure:
            click.echo(f"  failure         {result.failure}")
        if result.stood_still:
            click.echo(f"  motors stopped  {result.stood_still}")
        if result.plot is not None:
            click.echo(f"  picture         {result.plot}")
        if record_file is not None:
            click.echo(f"  recording       {record_file}")
    if follower is not None:
        if result.reason != "interrupted":  # Ctrl-C during the run quits; after a run, look at it
            click.echo(f"umlbot studio: {follower.url}  (the run has ended; Ctrl-C to quit)", err=as_json)
            with StopSignals() as after:
                after.running()
                after.stop.wait()
        follower.close()
    sys.exit(0 if result.ok else 1)


def _all(observers: list[Any]) -> Any:
    """One `run_sim` observe hook calling each of `observers` (None when there is none)."""
    if not observers:
        return None
    if len(observers) == 1:
        return observers[0]

    def observe(*args: Any) -> Any:
        finishers = [observer(*args) for observer in observers]

        def finish() -> None:
            for finisher in finishers:
                finisher()

        return finish

    return observe


def _run_fleet(model: Path, count: int, prefix: str | None, hub_port: int, sim_args: list[str],
               as_json: bool) -> None:
    """`--robots N`: the fleet on this machine; exit 0 only when every car succeeded."""
    from umlbot.compiler.api import compile_model
    from umlbot.fleet import CarResult, SimFleet, robot_ids

    robots = robot_ids(prefix or compile_model(model).name, count)
    fleet = SimFleet(model, robots, sim_args, hub_port or None)

    def report(result: CarResult) -> None:
        if as_json:
            return
        s = result.summary or {}
        why = s.get("failure") or s.get("reason") or result.stderr_tail[-300:]
        verdict = "ok" if result.ok else f"FAILED ({why})"
        click.echo(f"{result.robot:>10}: {s.get('reason', '-')}, {s.get('actions', 0)} actions, "
                   f"p50 {s.get('action_p50_ms')} ms: {verdict}")

    signals = StopSignals()
    with signals:
        signals.running()
        with fleet:
            if not as_json:
                click.echo(f"hub {fleet.hub_url}  (watch: umlbot studio --broker {fleet.hub_url}; "
                           f"umlbot monitor --broker {fleet.hub_url} --robot '*')")
                for robot in robots:
                    click.echo(f"{robot:>10}: leaf broker {fleet.fleet.leaf_url(robot)}")
            results = fleet.wait(signals.stop, report)
    if as_json:
        click.echo(json.dumps({"hub": fleet.hub_url, "robots": {
            r.robot: {"exit_code": r.exit_code, "summary": r.summary} for r in results.values()}}))
    sys.exit(0 if all(r.ok for r in results.values()) else 1)
