"""The real stereo camera: two Raspberry Pi camera modules (picamera2) or a USB stereo camera
(OpenCV `VideoCapture`), depth by `umlbot.services.stereo.depth` from a calibration file.

Not tested on hardware: the image sources below follow the picamera2 and OpenCV documentation;
the depth pipeline behind them is the one the simulator's tests check. Set-up and wiring:
docs/stereo.md.

Settings:
- `source`: `picamera2` (two CSI camera modules, a Pi 5 or a Compute Module: cameras 0 and 1) or
  `opencv` (a USB camera: one device giving both images side by side, `side_by_side: true`, or two
  devices `left_device`, `right_device`);
- `calibration` (required): the file `umlbot calibrate stereo` wrote, for this `width_px` x
  `height_px`;
- `frame_timeout_s`: no frame within this long → `DriverError` (the camera stopped).
"""

from __future__ import annotations

import threading
import time
from typing import Any, Literal

from pydantic import BaseModel, ConfigDict, Field

from umlbot.base.errors import ConfigError, DriverError
from umlbot.base.logs import get_logger
from umlbot.base.registry import DriverFactory
from umlbot.services.stereo.calibration import load_calibration
from umlbot.services.stereo.depth import DepthEngine, require_cv2
from umlbot.services.stereo.driver import DepthFrame

log = get_logger("umlbot.stereo.real")


class RealStereoSettings(BaseModel):
    """Deployment settings of a real camera pair."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    source: Literal["picamera2", "opencv"] = "picamera2"
    calibration: str = Field(description="the calibration file ('umlbot calibrate stereo')")
    width_px: int = Field(default=320, ge=64, le=2048)
    height_px: int = Field(default=240, ge=48, le=2048)
    left_device: int = Field(default=0, ge=0, description="camera number (picamera2) or /dev/videoN")
    right_device: int = Field(default=1, ge=0)
    side_by_side: bool = Field(default=False, description="opencv: one device, left half = left image")
    frame_timeout_s: float = Field(default=1.0, gt=0, le=30)
    min_range_cm: float = Field(default=24.0, ge=5, le=200)
    # read by the service (umlbot.services.stereo.service), for every driver
    frame_max_age_s: float = Field(default=0.05, ge=0, le=10, description="reuse a frame this long")
    beam_deg: float = Field(default=4.0, gt=0, le=60, description="distance(): median over this width")
    look_ahead_cm: float = Field(default=60.0, gt=0, le=1000, description="free_width(): up to here")


class _Sources:
    """Grabs one (left, right) grey pair; implementations below."""

    def grab(self) -> tuple[Any, Any]:
        raise NotImplementedError

    def close(self) -> None:
        raise NotImplementedError


class _OpenCVSources(_Sources):
    def __init__(self, settings: RealStereoSettings) -> None:
        cv2 = require_cv2()
        self._cv2 = cv2
        self.side_by_side = settings.side_by_side
        devices = [settings.left_device] if settings.side_by_side else [settings.left_device,
                                                                         settings.right_device]
        width = settings.width_px * (2 if settings.side_by_side else 1)
        self._captures = []
        for device in devices:
            capture = cv2.VideoCapture(device)
            if not capture.isOpened():
                self.close()
                raise DriverError(f"cannot open camera /dev/video{device}")
            capture.set(cv2.CAP_PROP_FRAME_WIDTH, width)
            capture.set(cv2.CAP_PROP_FRAME_HEIGHT, settings.height_px)
            self._captures.append(capture)

    def grab(self) -> tuple[Any, Any]:
        cv2 = self._cv2
        for capture in self._captures:  # grab both first, decode after: the pair is closer in time
            if not capture.grab():
                raise DriverError("the camera delivered no frame")
        images = []
        for capture in self._captures:
            ok, image = capture.retrieve()
            if not ok:
                raise DriverError("the camera delivered no frame")
            images.append(cv2.cvtColor(image, cv2.COLOR_BGR2GRAY))
        if self.side_by_side:
            half = images[0].shape[1] // 2
            return images[0][:, :half], images[0][:, half:]
        return images[0], images[1]

    def close(self) -> None:
        for capture in self._captures:
            capture.release()
        self._captures = []


class _Picamera2Sources(_Sources):
    def __init__(self, settings: RealStereoSettings) -> None:
        try:
            from picamera2 import Picamera2  # type: ignore[import-not-found, unused-ignore]
        except ImportError as exc:
            raise ConfigError("source picamera2 needs the picamera2 package (sudo apt install "
                              "python3-picamera2 on Raspberry Pi OS)") from exc
        self._cameras = []
        for number in (settings.left_device, settings.right_device):
            camera = Picamera2(number)
            config = camera.create_video_configuration(
                main={"size": (settings.width_px, settings.height_px), "format": "YUV420"})
            camera.configure(config)
            camera.start()
            self._cameras.append(camera)

    def grab(self) -> tuple[Any, Any]:
        # YUV420: the first `height` rows are the grey (Y) plane
        arrays = [camera.capture_array("main") for camera in self._cameras]
        height = arrays[0].shape[0] * 2 // 3
        return arrays[0][:height], arrays[1][:height]

    def close(self) -> None:
        for camera in self._cameras:
            camera.stop()
            camera.close()
        self._cameras = []


class RealStereoCamera:
    """A `StereoCamera` on real cameras; grabbing runs in a thread so a hung camera times out."""

    def __init__(self, component: str, settings: RealStereoSettings) -> None:
        self.component = component
        self.settings = settings
        calibration = load_calibration(settings.calibration)
        if tuple(calibration.image_size) != (settings.width_px, settings.height_px):
            raise ConfigError(f"{component}: the calibration is for {calibration.image_size[0]}x"
                              f"{calibration.image_size[1]}, the camera set to {settings.width_px}x"
                              f"{settings.height_px}: recalibrate at that size")
        self._engine = DepthEngine(calibration, min_range_m=settings.min_range_cm / 100.0)
        self._sources: _Sources = (_Picamera2Sources(settings) if settings.source == "picamera2"
                                   else _OpenCVSources(settings))
        self._lock = threading.Lock()
        self._closed = False
        log.info("stereo camera ready", component=component, source=settings.source)

    def read_depth(self) -> DepthFrame:
        with self._lock:
            if self._closed:
                raise DriverError(f"{self.component}: camera is closed")
            result: list[Any] = []
            error: list[BaseException] = []

            def grab() -> None:
                try:
                    result.append(self._sources.grab())
                except BaseException as exc:  # reported to the caller below
                    error.append(exc)

            worker = threading.Thread(target=grab, name=f"stereo-grab-{self.component}", daemon=True)
            worker.start()
            worker.join(self.settings.frame_timeout_s)
            if worker.is_alive() or error or not result:
                why = str(error[0]) if error else f"no frame within {self.settings.frame_timeout_s:g} s"
                raise DriverError(f"{self.component}: the camera delivers no frames: {why}")
            left, right = result[0]
        try:
            return self._engine.compute(left, right, time.monotonic())
        except ValueError as exc:
            raise DriverError(f"{self.component}: {exc}") from exc

    def time_s(self) -> float:
        return time.monotonic()

    def close(self) -> None:
        with self._lock:
            if self._closed:
                return
            self._closed = True
            self._sources.close()


def _create(component: str, settings: RealStereoSettings) -> RealStereoCamera:
    return RealStereoCamera(component, settings)


FACTORY = DriverFactory(RealStereoSettings, _create)
