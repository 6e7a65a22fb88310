"""`umlbot sim --studio`: the studio following a simulated run, with the track and the car."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING

from umlbot.studio.server import StudioServer, StudioThread
from umlbot.studio.sources import BrokerSource, WorldSource, studio_data, track_view

if TYPE_CHECKING:
    from umlbot.sim import World


class SimFollower:
    """Starts the studio when the sim's broker runs (`observe` is `run_sim`'s hook) and keeps the
    page served after the run, until `close()`."""

    def __init__(self, model: Path, port: int, announce: Callable[[str], None] | None = None) -> None:
        self.model = model
        self.port = port
        self.announce = announce
        self.url = ""
        self._thread: StudioThread | None = None
        self._sources: list[BrokerSource | WorldSource] = []

    def observe(self, world: World, broker_url: str, robot: str) -> Callable[[], None]:
        from umlbot.services.bus import BrokerSettings

        data = studio_data(self.model, robot)
        data.track = track_view(world)
        server = StudioServer(data, port=self.port, port_option="--studio-port")
        broker = BrokerSource(BrokerSettings.from_url(broker_url), robot, server.hub, data.call_timeout_s)
        server.tick = broker.tick
        self._thread = StudioThread(server)
        self.url = self._thread.start()
        if self.announce is not None:
            self.announce(self.url)
        self._sources = [broker, WorldSource(world, server.hub)]
        for source in self._sources:
            source.start()
        return self.finish

    def finish(self) -> None:
        """The run ended: stop following (the page keeps what it has)."""
        for source in self._sources:
            if isinstance(source, BrokerSource):  # its broker is gone with the run: not lost
                source.close(ended="the run has ended: the simulator and its broker are closed")
            else:
                source.close()
        self._sources = []

    def close(self) -> None:
        """Stop following and serving; safe to call twice."""
        self.finish()
        if self._thread is not None:
            self._thread.stop()
            self._thread = None
