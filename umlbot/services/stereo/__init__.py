"""The stereo camera service: distances from a calibrated camera pair (OpenCV), served over the bus.

The service (`service.py`) and the driver protocol (`driver.py`) need neither numpy nor OpenCV;
the drivers that see images (`sim.py`, `real.py`) do, through the extra `umlbot[stereo]`.
"""

from umlbot.services.stereo.driver import NO_READING, DepthFrame, StereoCamera

__all__ = ["NO_READING", "DepthFrame", "StereoCamera"]
