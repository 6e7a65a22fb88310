"""HC-SR04 range finder on the Raspberry Pi through the pigpio daemon.

A ping is a 10 µs high pulse on TRIG (`gpio_trigger`); the module answers with a high pulse on
ECHO whose length is the sound's round trip: cm = µs / 58. Both echo edges are timed by pigpio
(edge callbacks carry the daemon's microsecond tick) and the pulse length is `tickDiff(rise,
fall)`, which is right across the 32-bit tick wrap-around (every ~72 minutes). Pings are at least
`min_interval_s` (≥ 60 ms, the datasheet's measurement cycle) apart so an old echo is never taken
for a new one. When no falling edge comes within `echo_timeout_s`, or the pulse is as long as a
module's "nothing in range" pulse (≥ 30 ms, ~5 m), the reading is None. With `samples` > 1 the
result is the median of the pings that got an echo (None when none did).
"""

from __future__ import annotations

import statistics
import threading
import time
from typing import Any

from services.pigpio_connection import PigpioHandle
from services.registry import DriverFactory
from services.sonar.driver import HCSR04Settings
from umlbot.errors import DriverError
from umlbot.logs import get_logger

log = get_logger("umlbot.sonar.pigpio")

INPUT = 0  # pigpio.INPUT
OUTPUT = 1  # pigpio.OUTPUT
PUD_DOWN = 1  # pigpio.PUD_DOWN
EITHER_EDGE = 2  # pigpio.EITHER_EDGE
TRIGGER_PULSE_US = 10
US_PER_CM = 58.0
NO_ECHO_PULSE_US = 30_000
TICK_WRAP = 1 << 32


def tick_diff(t1: int, t2: int) -> int:
    """Microseconds from tick t1 to t2 across the 32-bit wrap (pigpio.tickDiff)."""
    diff = t2 - t1
    return diff + TICK_WRAP if diff < 0 else diff


class PigpioHCSR04:
    """One HC-SR04; satisfies `DistanceSensor`."""

    def __init__(self, component: str, settings: HCSR04Settings, pi: Any = None) -> None:
        self.component = component
        self.settings = settings
        self.max_range_cm = settings.max_range_cm
        self._lock = threading.Lock()  # one ping at a time
        self._edge_lock = threading.Lock()
        self._echo_done = threading.Event()
        self._rise_tick: int | None = None
        self._pulse_us: int | None = None
        self._armed = False
        self._last_ping = 0.0
        self._closed = False
        self._pins = PigpioHandle(component, settings.host, settings.port, pi)
        try:
            self._pins.call("set_mode", settings.trigger, OUTPUT)
            self._pins.call("write", settings.trigger, 0)
            self._pins.call("set_mode", settings.echo, INPUT)
            self._pins.call("set_pull_up_down", settings.echo, PUD_DOWN)
            self._callback = self._pins.call("callback", settings.echo, EITHER_EDGE, self._on_edge)
        except Exception:
            self._pins.close()
            raise
        log.info("sonar ready", component=component, trigger=settings.trigger, echo=settings.echo)

    def _on_edge(self, gpio: int, level: int, tick: int) -> None:
        # Runs on pigpio's callback thread.
        with self._edge_lock:
            if not self._armed:
                return
            if level == 1:
                self._rise_tick = tick
            elif level == 0 and self._rise_tick is not None:
                self._pulse_us = tick_diff(self._rise_tick, tick)
                self._armed = False
                self._echo_done.set()

    def _arm(self) -> None:
        with self._edge_lock:
            self._rise_tick = None
            self._pulse_us = None
            self._armed = True
            self._echo_done.clear()

    def _disarm(self) -> int | None:
        """Stop listening; the measured pulse length, if a whole pulse was seen."""
        with self._edge_lock:
            self._armed = False
            return self._pulse_us

    def _ping(self) -> float | None:
        wait = self._last_ping + self.settings.min_interval_s - time.monotonic()
        if wait > 0:
            time.sleep(wait)
        self._arm()
        self._last_ping = time.monotonic()
        self._pins.call("gpio_trigger", self.settings.trigger, TRIGGER_PULSE_US, 1)
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
        return float(statistics.median(echoes))

    def close(self) -> None:
        with self._lock:
            if self._closed:
                return
            self._closed = True
            try:
                self._callback.cancel()
            except Exception as exc:  # the connection may be gone; releasing it is what matters
                log.warning("cancel echo callback failed", component=self.component, error=str(exc))
            finally:
                self._pins.close()


def _create(component: str, settings: HCSR04Settings) -> PigpioHCSR04:
    return PigpioHCSR04(component, settings)


FACTORY = DriverFactory(HCSR04Settings, _create)
