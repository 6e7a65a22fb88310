"""HC-SR04 range finder through lgpio (the Raspberry Pi 5 and any recent Pi OS).

A ping drives TRIG high for at least 10 µs; the module answers with a high pulse on ECHO whose
length is the sound's round trip: cm = µs / 58. ECHO is claimed for alerts on both edges, and the
kernel timestamps each edge (nanoseconds) when it happens, so the pulse length does not depend on
how fast Python runs: µs = (fall - rise) / 1000. The rest is as for pigpio: pings at least
`min_interval_s` apart, None when no falling edge comes within `echo_timeout_s` or the pulse is a
module's "nothing in range" pulse (≥ 30 ms), the median of `samples` pings that got an echo.
"""

from __future__ import annotations

import statistics
import threading
import time
from typing import Any

from services.lgpio_connection import LgpioHandle
from services.registry import DriverFactory
from services.sonar.driver import HCSR04Settings
from umlbot.errors import DriverError
from umlbot.logs import get_logger

log = get_logger("umlbot.sonar.lgpio")

SET_PULL_DOWN = 64  # lgpio.SET_PULL_DOWN
BOTH_EDGES = 3  # lgpio.BOTH_EDGES
TRIGGER_PULSE_S = 10e-6
US_PER_CM = 58.0
NO_ECHO_PULSE_US = 30_000


class LgpioHCSR04:
    """One HC-SR04; satisfies `DistanceSensor`."""

    def __init__(self, component: str, settings: HCSR04Settings, lg: Any = None) -> None:
        self.component = component
        self.settings = settings
        self.max_range_cm = settings.max_range_cm
        self._lock = threading.Lock()  # one ping at a time
        self._edge_lock = threading.Lock()
        self._echo_done = threading.Event()
        self._rise_ns: int | None = None
        self._pulse_us: float | None = None
        self._armed = False
        self._last_ping = 0.0
        self._closed = False
        self._callback: Any = None
        self._pins = LgpioHandle(component, settings.chip, lg)
        try:
            self._pins.call("gpio_claim_output", settings.trigger, 0)
            self._pins.call("gpio_claim_alert", settings.echo, BOTH_EDGES, SET_PULL_DOWN)
            self._callback = self._pins.call("callback", settings.echo, BOTH_EDGES, self._on_edge)
        except Exception:
            self._pins.close()
            raise
        log.info("sonar ready", component=component, trigger=settings.trigger, echo=settings.echo,
                 chip=settings.chip)

    def _on_edge(self, chip: int, gpio: int, level: int, timestamp_ns: int) -> None:
        # Runs on lgpio's notification thread.
        with self._edge_lock:
            if not self._armed:
                return
            if level == 1:
                self._rise_ns = timestamp_ns
            elif level == 0 and self._rise_ns is not None:
                self._pulse_us = (timestamp_ns - self._rise_ns) / 1000
                self._armed = False
                self._echo_done.set()

    def _arm(self) -> None:
        with self._edge_lock:
            self._rise_ns = None
            self._pulse_us = None
            self._armed = True
            self._echo_done.clear()

    def _disarm(self) -> float | None:
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
        self._pins.call("gpio_write", self.settings.trigger, 1)
        time.sleep(TRIGGER_PULSE_S)  # sleeps at least this long: the module needs >= 10 µs
        self._pins.call("gpio_write", self.settings.trigger, 0)
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
            except Exception as exc:  # releasing the chip is what matters
                log.warning("cancel echo callback failed", component=self.component, error=str(exc))
            finally:
                self._pins.close()


def _create(component: str, settings: HCSR04Settings) -> LgpioHCSR04:
    return LgpioHCSR04(component, settings)


FACTORY = DriverFactory(HCSR04Settings, _create)
