"""What every distance sensor driver must provide, and the settings of an HC-SR04."""

from __future__ import annotations

import threading
import time
from typing import Any, Protocol, runtime_checkable

from pydantic import BaseModel, ConfigDict, Field, model_validator

from umlbot.base.errors import DriverError
from umlbot.base.logs import get_logger

log = get_logger("umlbot.sonar")

US_PER_CM = 58.0
#: a module's "nothing in range" pulse (~5 m): no echo
NO_ECHO_PULSE_US = 30_000


def median(values: list[float]) -> float:
    """`statistics.median` of a non-empty list of numbers, as a float, without importing
    statistics and the `random` it imports, which a service's process would hold for nothing."""
    ordered = sorted(values)
    middle = len(ordered) // 2
    return float(ordered[middle] if len(ordered) % 2 else (ordered[middle - 1] + ordered[middle]) / 2)


@runtime_checkable
class DistanceSensor(Protocol):
    """A range finder. `max_range_cm` is what the service reports when there is no echo."""

    max_range_cm: float

    def read_distance_cm(self) -> float | None:
        """One measurement in centimetres, or None when no echo came back (nothing in range).

        May block for the ping interval; raises `DriverError` when the hardware fails.
        """

    def close(self) -> None:
        """Release the pins/connection; idempotent."""


class HCSR04Settings(BaseModel):
    """Deployment settings of one HC-SR04 (BCM pin numbers, centimetres, seconds)."""

    model_config = ConfigDict(extra="forbid", frozen=True)

    trigger: int = Field(ge=0, le=27, description="GPIO of TRIG")
    echo: int = Field(ge=0, le=27, description="GPIO of ECHO (through a 5 V -> 3.3 V divider)")
    samples: int = Field(default=1, ge=1, le=15, description="median of this many pings")
    max_range_cm: float = Field(default=400.0, gt=0, le=1000, description="reported when no echo")
    min_interval_s: float = Field(default=0.06, ge=0.06, description="pause between pings (>= 60 ms)")
    echo_timeout_s: float = Field(default=0.04, gt=0, le=1, description="no echo within this -> None")
    host: str | None = Field(default=None, description="pigpiod host (default env PIGPIO_ADDR or localhost)")
    port: int | None = Field(default=None, description="pigpiod port (default env PIGPIO_PORT or 8888)")
    chip: int = Field(default=0, ge=0, description="lgpio: the gpiochip of the header pins (/dev/gpiochipN)")

    @model_validator(mode="after")
    def _distinct_pins(self) -> HCSR04Settings:
        if self.trigger == self.echo:
            raise ValueError(f"trigger and echo must be different pins, got {self.trigger}")
        return self

    @property
    def pins(self) -> tuple[int, ...]:
        """Every GPIO this sensor owns."""
        return (self.trigger, self.echo)


class PinHandle(Protocol):
    """What `HCSR04Pings` needs of a backend's pin connection."""

    closed: bool

    def close(self) -> None: ...


class HCSR04Pings:
    """How an HC-SR04 is read, above the pins; satisfies `DistanceSensor`.

    A ping is a high pulse of at least 10 µs on TRIG; the module answers with a high pulse on ECHO
    whose length is the sound's round trip: cm = µs / 58. Pings are at least `min_interval_s`
    (≥ 60 ms, the datasheet's measurement cycle) apart, so an old echo is never taken for a new
    one. When no falling edge comes within `echo_timeout_s`, or the pulse is as long as a module's
    "nothing in range" pulse (≥ 30 ms), the reading is None. With `samples` > 1 the result is the
    median of the pings that got an echo (None when none did).

    A backend sets `_pins` and `_callback` (its edge callback, cancelled on close), calls
    `_edge(level, stamp)` from its edge callback with its own timestamp, and provides `_trigger()`
    and `_pulse_us(rise, fall)` (the pulse length from two of its timestamps).
    """

    _pins: PinHandle

    def __init__(self, component: str, settings: HCSR04Settings) -> None:
        self.component = component
        self.settings = settings
        self.max_range_cm = settings.max_range_cm
        self._lock = threading.Lock()  # one ping at a time
        self._edge_lock = threading.Lock()
        self._echo_done = threading.Event()
        self._rise: int | None = None
        self._pulse: float | None = None
        self._armed = False
        self._last_ping = 0.0
        self._closed = False
        self._callback: Any = None

    def _trigger(self) -> None:
        raise NotImplementedError

    def _pulse_us(self, rise: int, fall: int) -> float:
        raise NotImplementedError

    def _edge(self, level: int, stamp: int) -> None:
        """An edge on ECHO (from the backend's callback thread)."""
        with self._edge_lock:
            if not self._armed:
                return
            if level == 1:
                self._rise = stamp
            elif level == 0 and self._rise is not None:
                self._pulse = self._pulse_us(self._rise, stamp)
                self._armed = False
                self._echo_done.set()

    def _arm(self) -> None:
        with self._edge_lock:
            self._rise = None
            self._pulse = None
            self._armed = True
            self._echo_done.clear()

    def _disarm(self) -> float | None:
        """Stop listening; the measured pulse length, if a whole pulse was seen."""
        with self._edge_lock:
            self._armed = False
            return self._pulse

    def _ping(self) -> float | None:
        wait = self._last_ping + self.settings.min_interval_s - time.monotonic()
        if wait > 0:
            time.sleep(wait)
        self._arm()
        self._last_ping = time.monotonic()
        self._trigger()
        got = self._echo_done.wait(self.settings.echo_timeout_s)
        pulse = self._disarm()
        if not got:
            pulse = None  # a half-seen pulse is no echo either
        if pulse is None or pulse >= NO_ECHO_PULSE_US:
            return None
        return min(pulse / US_PER_CM, self.max_range_cm)

    def read_distance_cm(self) -> float | None:
        with self._lock:
            if self._closed:
                raise DriverError(f"{self.component}: sensor is closed")
            readings = [self._ping() for _ in range(self.settings.samples)]
        echoes = [r for r in readings if r is not None]
        if not echoes:
            return None
        return median(echoes)

    def close(self) -> None:
        with self._lock:
            if self._closed:
                return
            self._closed = True
            try:
                if self._callback is not None:
                    self._callback.cancel()
            except Exception as exc:  # the connection may be gone; releasing it is what matters
                log.warning("cancel echo callback failed", component=self.component, error=str(exc))
            finally:
                self._pins.close()
