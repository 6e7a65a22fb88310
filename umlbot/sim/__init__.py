"""The 2D simulator: a track, the car's physics, world sharing for the sim drivers, the runner.

The sim drivers (`umlbot/services/<kind>/sim.py`) reach the world only through the seam the
services define (`umlbot.services.simworld`); this package implements it and serves it.
"""

from typing import TYPE_CHECKING

from umlbot.base.lazy import lazy_attributes
from umlbot.sim.sharing import WorldServer
from umlbot.sim.track import Track, bundled_tracks, find_track, load_track, parse_track
from umlbot.sim.world import CarSpec, World, WorldLoop, WorldSnapshot

if TYPE_CHECKING:
    from umlbot.sim.runner import Progress, SimOptions, run_sim

__all__ = [
    "CarSpec",
    "Progress",
    "SimOptions",
    "Track",
    "World",
    "WorldLoop",
    "WorldServer",
    "WorldSnapshot",
    "bundled_tracks",
    "find_track",
    "load_track",
    "parse_track",
    "run_sim",
]

#: heavy parts, imported on first use (umlbot.base.lazy.lazy_attributes)
__getattr__ = lazy_attributes(__name__, {
    "Progress": "umlbot.sim.runner",
    "SimOptions": "umlbot.sim.runner",
    "run_sim": "umlbot.sim.runner",
})
