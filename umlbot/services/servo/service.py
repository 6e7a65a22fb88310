"""The servo service's feature for one servo: `angle(degrees)`; outside 0..max → `out_of_range`."""

from __future__ import annotations

from typing import Any

from umlbot.services.bus import FeatureError
from umlbot.services.component_service import ComponentService
from umlbot.services.servo.driver import Servo


class ServoService(ComponentService):
    """One servo on the bus. State: `{"angle": degrees or null}` (null: no pulses: not commanded
    yet and no `initial_angle_deg`, or limp after a safe stop). A safe stop (the service
    stopping, the broker connection lost) switches the pulses off — the servo goes limp where it
    is — and publishes the null state; the next `angle` drives it again. The orchestrator's
    status does not stop servos."""

    kind = "servo"
    handlers = {"angle": "angle"}

    angle_deg: float | None = None

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        # the driver already turned the servo to `initial_angle_deg` (and validated it): say so
        initial = self.settings.get("initial_angle_deg")
        if isinstance(initial, int | float) and not isinstance(initial, bool):
            self.angle_deg = initial

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
            was_driven = self.angle_deg is not None
            self.servo.stop()
            self.angle_deg = None
        if was_driven:  # as a motor does: the retained state must not keep saying the old angle
            self.log.info("servo_limp", reason=reason)
            self.changed()
