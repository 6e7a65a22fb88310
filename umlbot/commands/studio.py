"""`umlbot studio`: the browser page that shows a model's diagrams and follows the robot live."""

from __future__ import annotations

import os
from pathlib import Path
from typing import TYPE_CHECKING

import click

from umlbot.base.stopsignals import StopSignals

if TYPE_CHECKING:
    from umlbot.studio.api import EditApi
    from umlbot.studio.fleet import FleetWatch
    from umlbot.studio.workspace import Workspace


@click.command(name="studio")
@click.argument("model", type=click.Path(path_type=Path))
@click.option("--broker", "broker_url", default=None, metavar="URL",
              help="Broker URL, e.g. mqtt://user:pass@host:1883 "
              "(default: $UMLBOT_BROKER or mqtt://127.0.0.1:1883).")
@click.option("--ca-file", type=click.Path(dir_okay=False, path_type=Path), default=None,
              help="CA certificate file for mqtts:// brokers.")
@click.option("--robot", metavar="ID", default=lambda: os.environ.get("UMLBOT_ROBOT") or None,
              show_default="$UMLBOT_ROBOT or the model's name",
              help="Robot id to follow (topics umlbot/<robot>/#).")
@click.option("--replay", "replay_file", type=click.Path(exists=True, dir_okay=False, path_type=Path),
              default=None, metavar="FILE",
              help="Play a recorded trace (umlbot run --trace FILE) instead of following the broker.")
@click.option("--host", default="127.0.0.1", show_default=True,
              help="Address to listen on; anything but loopback needs --allow-remote.")
@click.option("--port", type=click.IntRange(0, 65535), default=8080, show_default=True,
              help="Port to listen on (0 = any free port).")
@click.option("--allow-remote", is_flag=True,
              help="Allow --host to be a non-loopback address (anyone who reaches it sees the robot; "
              "the page is read-only then: no editing, no Run).")
@click.option("--fleet", is_flag=True,
              help="A fleet hub: list every robot seen on the broker (status, running nodes, faults, "
              "components); click one to follow it live (--robot: the one followed first; "
              "--robot '*' is --fleet too).")
@click.option("--open", "open_browser", is_flag=True, help="Open the page in the default browser.")
@click.option("--new", "new_model", is_flag=True,
              help="MODEL is a new model: a folder that does not exist yet (or an empty one); the page "
              "offers a starter model there.")
def command(model: Path, broker_url: str | None, ca_file: Path | None, robot: str | None,
            replay_file: Path | None, host: str, port: int, allow_remote: bool, fleet: bool,
            open_browser: bool, new_model: bool) -> None:
    """Serve the studio for MODEL: its diagrams, the robot's running nodes live, or a replay.

    The model is compiled by the studio; when it does not compile, the page lists the problems.
    A model folder can be edited in the page; with --new, MODEL is a new (or empty) folder and the
    page offers a starter model.
    Runs until Ctrl-C or SIGTERM.
    """
    from umlbot.base.logs import configure_logging
    from umlbot.services.bus import BrokerSettings, redact_url, resolve_broker_url
    from umlbot.studio.server import StudioServer, StudioThread, check_bind, is_loopback
    from umlbot.studio.sources import RobotFollower, replay_data, studio_data

    # the terminal says what a person needs (the URL, one line per Run, problems); the services
    # and the orchestrator of a Run log their INFO only when asked for (--log-level)
    if click.get_current_context().find_root().params.get("log_level") is None and not os.environ.get(
            "UMLBOT_LOG_LEVEL"):
        configure_logging("WARNING")
    # a page others can reach is read-only: its write token would be theirs too (docs/studio.md)
    remote = not is_loopback(host)
    check_model_path(model, new_model)
    editable = (replay_file is None and not remote
                and (model.is_dir() or (not model.exists() and model.parent.is_dir())))
    if not model.exists() and not editable:
        needs = "an existing parent folder"
        if remote and model.parent.is_dir():
            needs = "a loopback --host: a page others can reach does not edit"
        raise click.BadParameter(f"{model} does not exist (a new model folder needs {needs})",
                                 param_hint="'MODEL'")
    check_bind(host, allow_remote)
    if robot is not None and robot.strip() == "*":  # every robot on the broker: the fleet view
        fleet, robot = True, None
    if fleet and replay_file is not None:
        raise click.UsageError("--fleet follows robots on a broker: not with --replay")
    api: EditApi | None = None
    if editable:
        from umlbot.studio.api import EditApi
        from umlbot.studio.workspace import Workspace

        workspace = Workspace(model)  # checks the model once; the page's first view is that check
        data = studio_data(model, robot, result=workspace.result)
        server = StudioServer(data, host=host, port=port, allow_remote=allow_remote)
        api = EditApi(workspace)
        server.api = api
        api.on_run_end = click.echo  # one line per Run, as the URL line
        data.edit = api.hello
    else:
        from umlbot.compiler.api import check_model

        result = check_model(model)
        data = studio_data(model, robot, mode="replay" if replay_file else "live", result=result)
        server = StudioServer(data, host=host, port=port, allow_remote=allow_remote)
    from umlbot.studio.layouts import LayoutCache

    server.layouts = LayoutCache.for_model(model)  # with the model's shipped layouts, if any
    source: RobotFollower | None = None
    what = f"replay of {replay_file}"
    notes: list[str] = []
    if replay_file is not None:
        data.replay = replay_data(replay_file, data.robot, result.model)
        notes = data.replay["notes"]
    else:
        url = resolve_broker_url(broker_url)
        settings = BrokerSettings.from_url(url, ca_file=ca_file)
        what = f"robot {data.robot} on {redact_url(url)}"
        if editable and workspace.empty and robot is None:  # no name yet: none is made up
            what = f"a new model, followed under the name you give it, on {redact_url(url)}"
        source = RobotFollower(settings, data.robot, server.hub, data.call_timeout_s)
        server.tick = source.tick
        if api is not None and robot is None:
            follower = source

            def follow_name(name: str) -> None:  # the robot id is the model's name: follow it
                before, data.robot = data.robot, name  # (a page opening meanwhile says the new one)
                try:
                    follower.follow(name)
                except Exception:
                    data.robot = before
                    raise

            api.on_name = follow_name
    watch: FleetWatch | None = None
    if fleet and source is not None:
        from umlbot.studio.fleet import FleetWatch

        follower_ = source

        def follow_robot(name: str) -> None:  # a robot clicked in the fleet view
            follower_.follow(name)
            data.robot = name

        watch = FleetWatch(settings, redact_url(url), follow_robot)
        server.extra_routes.append(watch.routes)
        data.fleet = True
        what = f"every robot on {redact_url(url)} (fleet view), following {data.robot}"
    errors = sum(1 for d in data.diagnostics if d["severity"] == "error")
    studio = StudioThread(server)
    with StopSignals() as signals:
        page = studio.start()
        try:
            if source is not None:
                source.start()
            if watch is not None:
                watch.start()
            signals.running()
            click.echo(f"umlbot studio: {page}  ({what}; Ctrl-C to quit)")
            if editable and workspace.empty:
                state = "does not exist yet" if not model.exists() else "holds no model yet"
                click.echo(f"umlbot studio: {model} {state}: the page offers a starter model "
                           "(type the robot's name, press 'Create the model')")
            if errors and not (editable and workspace.empty):  # no model yet is not an error
                click.echo(f"  the model has {errors} error(s): the page lists them", err=True)
            for note in notes:
                click.echo(f"  warning: {note}", err=True)
            if remote and replay_file is None and model.is_dir():
                click.echo("  read-only: the page can be reached from other machines, so it does not "
                           "edit or run the model (to edit, keep the studio on 127.0.0.1 and use an "
                           "SSH tunnel; docs/studio.md, Security)", err=True)
            if editable and workspace.layout_problem is not None:
                click.echo(f"  {workspace.layout_problem}: the page starts without the saved "
                           "positions (saving rewrites the file)", err=True)
            if open_browser:
                import webbrowser

                webbrowser.open(page)
            signals.stop.wait()
        finally:
            if watch is not None:
                watch.close()
            if source is not None:
                source.close()
            studio.stop()
            if editable:
                keep_unsaved(workspace)


def check_model_path(model: Path, new_model: bool) -> None:
    """MODEL is a model (a folder with its files, or one .yaml file), or, with --new, a folder that
    does not exist yet or is empty: anything else is a usage error saying what was found and how to
    ask for a new model (a typo in a path must not start a new model there)."""
    from umlbot.studio.workspace import model_files

    new_hint = f"to start a new model there, run: umlbot studio --new {model}"
    if new_model:
        if model.is_file() or (model.is_dir() and model_files(model)):
            raise click.BadParameter(f"{model} already holds a model: --new starts one in a new or "
                                     "empty folder (leave --new out to open this one)", param_hint="'MODEL'")
        if not model.exists() and not model.parent.is_dir():
            raise click.BadParameter(f"{model} does not exist and neither does its folder "
                                     f"{model.parent}: a new model folder needs an existing parent folder",
                                     param_hint="'MODEL'")
        return
    if model.is_file():
        if model.suffix in (".yaml", ".yml"):
            return
        raise click.BadParameter(f"{model} is not a model: a model is a folder holding model.yaml "
                                 "(e.g. models/robot_car), or one .yaml file", param_hint="'MODEL'")
    if model.is_dir():
        if model_files(model):
            return
        raise click.BadParameter(f"{model} holds no model (no model.yaml in it); {new_hint}",
                                 param_hint="'MODEL'")
    guess = close_sibling(model)
    also = f" (did you mean {guess}?)" if guess is not None else ""
    raise click.BadParameter(f"{model} does not exist{also}; {new_hint}", param_hint="'MODEL'")


def close_sibling(model: Path) -> Path | None:
    """The folder beside `model` whose name is closest to its name, if one is close (a typo)."""
    import difflib

    try:
        names = [p.name for p in model.parent.iterdir() if p.is_dir()]
    except OSError:
        return None
    found = difflib.get_close_matches(model.name, names, n=1, cutoff=0.75)
    return model.parent / found[0] if found else None


def keep_unsaved(workspace: Workspace) -> None:
    """The studio quits with unsaved edits: keep them in the folder's recovery file (the model's
    files stay as they are) and say so in one line; the next start offers them back."""
    with workspace.lock:
        try:
            path = workspace.keep_unsaved()
        except (OSError, ValueError) as exc:
            files = ", ".join(workspace.changed_files()) or "the layout"
            click.echo(f"umlbot studio: unsaved edits of {files} were LOST: cannot write the recovery "
                       f"file: {exc}", err=True)
            return
    if path is not None:
        files = ", ".join(workspace.changed_files()) or "the layout"
        click.echo(f"umlbot studio: unsaved edits of {files} kept in {path} (not saved; the next "
                   "`umlbot studio` offers to restore them)", err=True)
