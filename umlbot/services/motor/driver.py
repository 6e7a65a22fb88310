"""What every motor channel driver must provide, and the settings of an L298N channel.

A channel is one side of the robot (one H-bridge output). Units outside a driver are percent and
booleans; PWM ranges, frequencies and pin levels stay inside the driver.
"""

from __future__ import annotations

import threading
from typing import Protocol, runtime_checkable

from pydantic import BaseModel, ConfigDict, Field, model_validator

BcmPin = int


@runtime_checkable
class MotorChannel(Protocol):
    """One DC-motor channel. Every method may raise `DriverError`; `close()` twice is safe.

    Must provide: `set_enabled`, `set_direction`, `set_duty_cycle`, `stop`, `renew`, `close`.
    """

    def set_enabled(self, enabled: bool) -> None:
        """Drive (True) or stop the motor (False: coast, or brake where the settings say so)."""

    def set_direction(self, clockwise: bool) -> None:
        """Turning direction; True = clockwise (forward)."""

    def set_duty_cycle(self, percent: float) -> None:
        """Drive strength in percent, 0..100; takes effect immediately when enabled."""

    def stop(self) -> None:
        """Safe state: disabled and duty 0. Never raises for an already stopped channel."""

    def renew(self) -> bool:
        """Renew the deadman outside this process; the motor service calls it every safety round
        (`umlbot.services.host.TICK_S`) while the motor is enabled. A driver with a deadman (pigpio,
        lgpio, sim) has the hardware path stop the motor by itself when no renewal (and no
        command) came for its `watchdog_s`, so that a frozen or killed service cannot leave it
        running. False when the deadman fired since the last renewal (the motor was stopped
        behind the service's back); True otherwise, and always for a driver without one."""

    def close(self) -> None:
        """Stop the motor and release the pins/connection; idempotent."""


class L298NSettings(BaseModel):
    """Deployment settings of one L298N channel (BCM pin numbers).

    Without `enable` the ENA/ENB jumper is fitted: PWM goes to the input pin of the direction and
    "stopped" means both inputs low (the L298N's fast stop). With `enable`, PWM goes to the enable
    pin and `enabled(false)` lets the motor coast (EN low), or brakes (EN high, IN1 = IN2 = low)
    when `brake` is true.
    """

    model_config = ConfigDict(extra="forbid", frozen=True)

    in1: BcmPin = Field(ge=0, le=27, description="GPIO of IN1 (high = clockwise)")
    in2: BcmPin = Field(ge=0, le=27, description="GPIO of IN2 (high = anticlockwise)")
    enable: BcmPin | None = Field(default=None, ge=0, le=27, description="GPIO of ENA/ENB")
    pwm_frequency_hz: int = Field(default=1000, ge=10, le=8000, description="software PWM frequency")
    brake: bool = Field(default=False, description="stopping brakes instead of coasting")
    watchdog_s: float = Field(default=2.0, ge=0, description="stop after this long without a command, "
                              "a heartbeat of the orchestrator or a renewal of the deadman (0: never)")
    invert: bool = Field(default=False, description="swap clockwise/anticlockwise (motor wired reversed)")
    host: str | None = Field(default=None, description="pigpiod host (default env PIGPIO_ADDR or localhost)")
    port: int | None = Field(default=None, description="pigpiod port (default env PIGPIO_PORT or 8888)")
    chip: int = Field(default=0, ge=0, description="lgpio: the gpiochip of the header pins (/dev/gpiochipN)")

    @model_validator(mode="after")
    def _distinct_pins(self) -> L298NSettings:
        pins = [p for p in (self.in1, self.in2, self.enable) if p is not None]
        if len(set(pins)) != len(pins):
            raise ValueError(f"in1, in2 and enable must be different pins, got {pins}")
        return self

    @property
    def pins(self) -> tuple[BcmPin, ...]:
        """Every GPIO this channel owns."""
        return tuple(p for p in (self.in1, self.in2, self.enable) if p is not None)


class PinHandle(Protocol):
    """What `L298NBridge` needs of a backend's pin connection."""

    closed: bool

    def close(self) -> None: ...


class L298NBridge:
    """The L298N channel's truth table and safety rules, above the pins; satisfies `MotorChannel`.

    Truth table of one channel (EN = enable, IN1/IN2 = inputs): EN 1, IN1 1, IN2 0 clockwise;
    EN 1, IN1 0, IN2 1 anticlockwise; EN 1 with IN1 = IN2 fast stop (brake); EN 0 coast. With an
    enable pin the duty cycle is PWM on EN and the inputs set the direction; without one (the
    ENA/ENB jumper fitted, as on the reference robot) the PWM goes to the input of the direction
    while the other input is low, and stopped means both inputs low. Changing direction while
    driving stops first, so both inputs of a bridge arm are never driven at once.

    A backend (pigpio, lgpio) sets `_pins` and provides `_level(pin, level)` (a plain level,
    ending any PWM on the pin) and `_pwm(pin)` (PWM at the current `_percent`); its deadman
    (`renew`) overrides `_deadman(driving)` (called at the end of every change, with whether the
    motor now drives), `_renew()` (only while it drives) and `_release()` (before the pins are
    released). Starts stopped; `close()` leaves it stopped.
    """

    _pins: PinHandle

    def __init__(self, component: str, settings: L298NSettings) -> None:
        self.component = component
        self.settings = settings
        self._lock = threading.Lock()
        self._enabled = False
        self._clockwise = True
        self._percent = 0.0
        self._closed = False

    def _level(self, pin: int, level: int) -> None:
        raise NotImplementedError

    def _pwm(self, pin: int) -> None:
        raise NotImplementedError

    # MotorChannel ---------------------------------------------------------------------------

    def set_enabled(self, enabled: bool) -> None:
        with self._lock:
            self._enabled = enabled
            self._apply()

    def set_direction(self, clockwise: bool) -> None:
        with self._lock:
            if clockwise != self._clockwise and self._driving():
                self._halt()  # never drive both inputs of a bridge arm at once while switching
            self._clockwise = clockwise
            self._apply()

    def set_duty_cycle(self, percent: float) -> None:
        if not 0 <= percent <= 100:
            raise ValueError(f"duty cycle must be 0..100 %, got {percent}")
        with self._lock:
            self._percent = float(percent)
            self._apply()

    def stop(self) -> None:
        with self._lock:
            self._enabled = False
            self._percent = 0.0
            if not self._pins.closed:
                self._apply()

    def renew(self) -> bool:
        with self._lock:
            if self._closed or self._pins.closed or not self._driving():
                return True
            return self._renew()

    def close(self) -> None:
        with self._lock:
            if self._closed:
                return
            self._closed = True
            self._enabled = False
            self._percent = 0.0
            try:
                self._apply()
                self._release()
            finally:
                self._pins.close()

    # the deadman (backends override) ----------------------------------------------------------

    def _deadman(self, driving: bool) -> None:
        """After every change: arm the deadman when the motor drives, disarm it when it stopped."""

    def _renew(self) -> bool:
        """`renew` while the motor drives; False when the deadman had fired."""
        return True

    def _release(self) -> None:
        """Give back what the deadman holds (the channel is stopped)."""

    # the truth table ---------------------------------------------------------------------------

    def _driving(self) -> bool:
        return self._enabled and self._percent > 0

    def _forward_pin(self) -> tuple[int, int]:
        """(driving input, other input) for the current direction."""
        s = self.settings
        forward = self._clockwise != s.invert
        return (s.in1, s.in2) if forward else (s.in2, s.in1)

    def _halt(self) -> None:
        s = self.settings
        if s.enable is not None:
            self._level(s.enable, 0)
        self._level(s.in1, 0)
        self._level(s.in2, 0)

    def _apply(self) -> None:
        s = self.settings
        drive, other = self._forward_pin()
        if not self._driving():
            if s.enable is not None and s.brake:
                self._level(s.in1, 0)
                self._level(s.in2, 0)
                self._level(s.enable, 1)  # EN high, IN1 = IN2: fast stop
            else:
                self._halt()  # EN low: coast; without EN both inputs low (the L298N's stop)
            self._deadman(False)
            return
        self._level(other, 0)
        if s.enable is not None:
            self._level(drive, 1)
            self._pwm(s.enable)
        else:
            self._pwm(drive)
        self._deadman(True)
