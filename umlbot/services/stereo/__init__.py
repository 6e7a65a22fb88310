"""The stereo camera service: distances from a calibrated camera pair (OpenCV), served over the bus.

The service (`service.py`), the driver protocol (`driver.py`) and the calibration file
(`calibration.py`) need neither numpy nor OpenCV; the depth pipeline (`depth.py`), the
calibration from chessboard pairs (`calibrate.py`) and the drivers that see images (`sim.py`,
`real.py`) do, through the extra `umlbot[stereo]`, and are imported on first use.
"""

from umlbot.base.lazy import lazy_attributes
from umlbot.services.stereo.calibration import Calibration, load_calibration, save_calibration
from umlbot.services.stereo.driver import NO_READING, DepthFrame, StereoCamera

__all__ = ["NO_READING", "Calibration", "DepthFrame", "StereoCamera", "calibrate_pairs",
           "load_calibration", "read_pairs", "save_calibration"]

#: the parts that need numpy and OpenCV, imported on first use
__getattr__ = lazy_attributes(__name__, {
    "calibrate_pairs": "umlbot.services.stereo.calibrate",
    "read_pairs": "umlbot.services.stereo.calibrate",
})
