"""The servo service's feature for one servo: `angle(degrees)`; outside 0..max → `out_of_range`."""

from __future__ import annotations

from typing import Any

from services.bus.server import FeatureError
from services.component_service import ComponentService
from services.servo.driver import Servo


class ServoService(ComponentService):
    """One servo on the bus. State: `{"angle": degrees or null}` (null: no pulses yet / stopped)."""

    kind = "servo"
    handlers = {"angle": "angle"}

    angle_deg: float | None = None

    @property
    def servo(self) -> Servo:
        servo: Servo = self.driver
        return servo

    def angle(self, degrees: int) -> None:
        limit = self.servo.max_angle_deg
        if not 0 <= degrees <= limit:
            raise FeatureError("out_of_range", f"degrees={degrees} is outside 0..{limit:g} °")
        with self.lock:
            self.servo.set_angle(degrees)
            self.angle_deg = degrees
        self.changed()

    def state(self) -> dict[str, Any]:
        with self.lock:
            return {"angle": self.angle_deg}

    def safe_stop(self, reason: str) -> None:
        with self.lock:
            self.servo.stop()
            self.angle_deg = None
