"""The studio's Run button: the working copy in the simulator, followed live by the page.

One run at a time, in a thread: the working copy is written to a private temp folder (nothing is
saved), then `run_sim` runs it exactly as `umlbot sim` does (embedded broker, sim drivers); its
`observe` hook connects the studio's hub to the run's broker and world, as `umlbot sim --studio`
does, so the page's live view follows it.
"""

from __future__ import annotations

import contextlib
import shutil
import tempfile
import threading
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Any

from umlbot.base.logs import get_logger
from umlbot.studio.sources import BrokerSource, WorldSource, track_view
from umlbot.studio.workspace import Conflict

if TYPE_CHECKING:
    from umlbot.sim import World
    from umlbot.studio.hub import Hub

log = get_logger(__name__)

#: simulation speed of a studio run (sim seconds per wall second): slow enough to watch.
RUN_SPEED = 2.0


def resolve_track(track: Any, model_root: Path) -> Path:
    """A bundled track's name, or a track file inside the model folder (nothing else)."""
    from umlbot.sim import bundled_tracks
    from umlbot.studio.workspace import safe_path, shown

    if not isinstance(track, str) or not track:
        raise ValueError("'track' names a bundled track (see /api/tracks) or a file in the model folder")
    bundled = bundled_tracks()
    if track in bundled:
        return bundled[track]
    path = safe_path(model_root, track)
    try:
        is_file = path.is_file()
    except OSError as exc:  # e.g. a name too long for the system
        raise ValueError(f"no track {shown(track)} ({exc.strerror or exc})") from None
    if not is_file:
        raise ValueError(f"no track {shown(track)} (bundled: {', '.join(bundled)})")
    return path


def run_line(track: str, speed: float, result: dict[str, Any]) -> str:
    """A Run of the studio in one plain line for its terminal: where, how it ended, the figures,
    and why the motors stood still when a safety stop stopped them."""
    reason = result.get("reason")
    how = {
        "goal": "the car reached the goal",
        "collision": "stopped: the car hit a wall",
        "timeout": "time is up: the goal was not reached",
        "interrupted": "stopped from the page",
        "orchestrator ended": "the model came to its end",
        "failed": "could not start",
    }.get(str(reason), f"ended ({reason})")
    figures = []
    if result.get("sim_s") is not None:
        figures.append(f"{result['sim_s']:.1f} s simulated")
    if result.get("distance_m") is not None:
        figures.append(f"{result['distance_m']:.2f} m")
    if result.get("collisions"):
        figures.append(f"{result['collisions']} collision(s)")
    line = f"umlbot studio: run on {track} at {speed:g}x: {how}"
    if figures:
        line += f" ({', '.join(figures)})"
    if result.get("failure"):
        line += f": {result['failure']}"
    if result.get("stood_still"):
        line += f"; motors stopped: {result['stood_still']}"
    return line


class StudioRun:
    """Runs the working copy in the simulator, one run at a time; frames go through `broadcast`."""

    def __init__(self, hub: Hub, broadcast: Callable[[dict[str, Any]], None],
                 say: Callable[[str], None] | None = None) -> None:
        self.hub = hub
        self.broadcast = broadcast
        #: told one plain line per run, at its end (the studio's terminal)
        self.say = say
        self._thread: threading.Thread | None = None
        self._stop = threading.Event()
        self._sources: list[BrokerSource | WorldSource] = []
        self.last: dict[str, Any] | None = None
        self._track_name = ""
        #: the run going on, for a page that opens during it (hello.edit.run).
        self.current: dict[str, Any] = {"running": False}

    @property
    def running(self) -> bool:
        return self._thread is not None and self._thread.is_alive()

    def start(self, files: dict[str, bytes], track: Path, speed: float = RUN_SPEED) -> dict[str, Any]:
        if self.running:
            raise Conflict({"error": "a run is going on: stop it first"})
        folder = Path(tempfile.mkdtemp(prefix="umlbot-studio-run-"))
        model = folder / "model"
        for rel, data in files.items():
            target = model / rel
            target.parent.mkdir(parents=True, exist_ok=True)
            target.write_bytes(data)
        self._stop = threading.Event()
        self._track_name = track.stem
        self._thread = threading.Thread(target=self._run, args=(folder, model, track, speed),
                                        name="studio-run", daemon=True)
        self._thread.start()
        return {"running": True, "track": track.stem}

    def stop(self, timeout: float = 30.0) -> dict[str, Any]:
        self._stop.set()
        thread = self._thread
        if thread is not None and thread is not threading.current_thread():
            thread.join(timeout)
        return {"running": self.running, "result": self.last}

    def _observe(self, world: World, broker_url: str, robot: str) -> Callable[[], None]:
        from umlbot.services.bus import BrokerSettings

        self.hub.reset_world()  # a page opening later gets this run's world, not the last one's
        self.current = {"running": True, "robot": robot, "track": track_view(world)}
        self.broadcast({"type": "run", "state": "running", **self.current})
        self._sources = [BrokerSource(BrokerSettings.from_url(broker_url), robot, self.hub, origin="run"),
                         WorldSource(world, self.hub)]
        for source in self._sources:
            source.start()
        return self._finish

    def tick(self) -> None:
        """About once a second: the run's broker connection (the toolbar says it), calls that
        stayed unanswered."""
        for source in list(self._sources):
            if isinstance(source, BrokerSource):
                source.tick()

    def _finish(self) -> None:
        for source in self._sources:
            with contextlib.suppress(Exception):
                source.close()
        self._sources = []

    def _run(self, folder: Path, model: Path, track: Path, speed: float) -> None:
        from umlbot.sim import SimOptions, run_sim

        try:
            result = run_sim(SimOptions(model=model, track=track, speed=speed, port=0), stop=self._stop,
                             observe=self._observe)
            self.last = {"reason": result.reason, "goal_reached": result.goal_reached,
                         "collisions": result.collisions, "sim_s": round(result.sim_s, 2),
                         "distance_m": round(result.distance_m, 2), "failure": result.failure,
                         # why the motors stopped before the end (the page may show it)
                         "stood_still": result.stood_still,
                         # component -> the safety stop its service made (watchdog, …)
                         "safety_stops": dict(result.safety_stops)}
        except Exception as exc:  # a bad model or track: tell the page, never crash the studio
            log.warning("studio run failed", error=str(exc))
            self.last = {"reason": "failed", "failure": str(exc)}
        finally:
            self._finish()
            shutil.rmtree(folder, ignore_errors=True)
        if self.say is not None:
            with contextlib.suppress(Exception):
                self.say(run_line(self._track_name, speed, self.last))
        # the track stays, so a page opening after the run draws it with the run's last world
        self.current = {"running": False, "result": self.last,
                        **({"track": self.current["track"]} if "track" in self.current else {})}
        self.broadcast({"type": "run", "state": "ended", **self.current})
