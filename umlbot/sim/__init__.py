"""The 2D simulator: a track, the car's physics, world sharing for the sim drivers, the runner.

Nothing outside the sim drivers (`umlbot/services/<kind>/sim.py`) and `umlbot sim` knows it exists.
"""

from umlbot.sim.sharing import WorldServer, attach_local_world, connect_world
from umlbot.sim.track import Track, load_track, parse_track
from umlbot.sim.world import CarSpec, World, WorldLoop, WorldSnapshot

__all__ = [
    "CarSpec",
    "Track",
    "World",
    "WorldLoop",
    "WorldServer",
    "WorldSnapshot",
    "attach_local_world",
    "connect_world",
    "load_track",
    "parse_track",
]
