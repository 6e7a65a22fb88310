"""A fake `lgpio` module: the lgpio Python API without a Raspberry Pi, for tests and demos.

`FakeLgpio()` is used where the `lgpio` module would be: it has the module's function names,
argument order and defaults, constants, return values and errors (`error` carries lgpio's own
messages, e.g. ``'GPIO busy'``, and `str()` of it is the message's repr, as in lgpio) for what
umlbot's lgpio drivers use: `gpiochip_open`/`gpiochip_close` (handles carry the chip number in
bits 16+), line claims (`gpio_claim_input`, `gpio_claim_output`, `gpio_claim_alert`,
`gpio_free`; a line claimed through another handle is ``GPIO busy``), `gpio_read`/`gpio_write`,
software PWM (`tx_pwm`, with lgpio's queue: see below) and servo pulses (`tx_servo`), and alert
`callback`s with nanosecond timestamps.

PWM as lgpio's TX thread sends it: `tx_pwm(..., pulse_cycles=N)` sends N cycles and then writes
the line low and ends (N = 0: for ever). A `tx_pwm` on a line whose PWM runs is queued (at most
`TX_BUF` entries, then ``TX queue full``): it replaces an endless current entry at once (lgpio: at
the end of the current cycle) and follows a finite one when its cycles are done; `tx_room` says
how many entries are free, `tx_busy` whether PWM runs. Finite entries end in wall time, on a
thread of the fake (lgpio's TX thread is a thread of the process too: it stops with it).

It records every call in `calls` and can simulate HC-SR04 range finders: after
`attach_hcsr04(trigger, echo, distance_cm)` every high-to-low write on `trigger` makes the echo
line go high and low again `distance_cm * 58` µs later; when the echo line is claimed for alerts
the edges reach its callbacks on a separate thread, as lgpio's notification thread delivers them.
Timestamps are virtual: they advance only by the simulated durations and `advance_ns()`.

`state()` returns every line's claim, level, PWM and servo settings; with `state_file` the same
JSON is rewritten after every output change (see `umlbot.services.pins.lgpio`).
"""

from __future__ import annotations

import contextlib
import json
import os
import queue
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from umlbot.testing.pigpio import FakeHCSR04  # the same simulated module behind either fake

# Constants with lgpio's values.
LOW = 0
HIGH = 1
TIMEOUT = 2
SET_ACTIVE_LOW = 4
SET_OPEN_DRAIN = 8
SET_OPEN_SOURCE = 16
SET_PULL_UP = 32
SET_PULL_DOWN = 64
SET_PULL_NONE = 128
RISING_EDGE = 1
FALLING_EDGE = 2
BOTH_EDGES = 3
TX_PWM = 0
TX_WAVE = 1

# Error codes and lgpio's texts for them (`lgpio.error_text`).
OKAY = 0
BAD_HANDLE = -5
BAD_GPIO_NUMBER = -73
CANNOT_OPEN_CHIP = -78
GPIO_BUSY = -79
GPIO_NOT_ALLOCATED = -80
BAD_SERVO_FREQ = -100
BAD_SERVO_WIDTH = -101
BAD_PWM_FREQ = -102
BAD_PWM_DUTY = -103
GPIO_NOT_AN_OUTPUT = -104
TX_QUEUE_FULL = -96
BAD_TX_TYPE = -10
_ERROR_TEXT: dict[int, str] = {
    BAD_HANDLE: "unknown handle",
    BAD_GPIO_NUMBER: "bad GPIO number",
    CANNOT_OPEN_CHIP: "can not open gpiochip",
    GPIO_BUSY: "GPIO busy",
    GPIO_NOT_ALLOCATED: "GPIO not allocated",
    BAD_SERVO_FREQ: "bad servo frequency",
    BAD_SERVO_WIDTH: "bad servo pulsewidth",
    BAD_PWM_FREQ: "bad PWM frequency",
    BAD_PWM_DUTY: "bad PWM dutycycle",
    GPIO_NOT_AN_OUTPUT: "GPIO not set as an output",
    TX_QUEUE_FULL: "TX queue full",
    BAD_TX_TYPE: "bad tx type for GPIO and group",
}
#: entries of a line's PWM queue, the current one included (lgpio's LG_TX_BUF)
TX_BUF = 10

#: Lines of the Raspberry Pi 5's RP1 gpiochip (the header's GPIO 0..27 are its first lines).
PI5_LINES = 54
US_PER_CM = 58.0  # round trip, as the HC-SR04 datasheet states


class error(Exception):
    """What lgpio raises for a negative status (`lgpio.error`): `value` is lgpio's message."""

    def __init__(self, value: str) -> None:
        super().__init__(value)
        self.value = value

    def __str__(self) -> str:
        return repr(self.value)


def error_text(errnum: int) -> str:
    """lgpio's description of an error code."""
    return _ERROR_TEXT.get(errnum, f"unknown error {errnum}")


def _fail(code: int) -> error:
    return error(error_text(code))


@dataclass
class LineState:
    """Everything the fake knows about one line (GPIO) of a chip."""

    claim: str = "free"  # free, input, output, alert
    handle: int | None = None
    flags: int = 0
    edges: int = 0
    level: int = 0
    pwm_frequency: float = 0.0
    pwm_duty_percent: float = 0.0
    #: cycles of the current PWM entry (0: endless) and when they are done (`time.monotonic()`)
    pwm_cycles: int = 0
    pwm_ends_at: float | None = None
    #: queued PWM entries after the current one: (frequency, duty %, cycles; 0 = endless)
    pwm_queue: list[tuple[float, float, int]] = field(default_factory=list)
    servo_pulse_us: int = 0
    servo_frequency: int = 0

    @property
    def duty_fraction(self) -> float:
        """The output as a fraction 0..1: the PWM duty while PWM runs, else the level of an output."""
        if self.pwm_frequency:
            return self.pwm_duty_percent / 100
        return float(self.level) if self.claim == "output" and not self.servo_pulse_us else 0.0

    def stop_tx(self) -> None:
        self.pwm_frequency = self.pwm_duty_percent = 0.0
        self.pwm_cycles, self.pwm_ends_at, self.pwm_queue = 0, None, []
        self.servo_pulse_us = self.servo_frequency = 0

    def start_pwm(self, frequency: float, duty: float, cycles: int, at: float) -> None:
        """Make (frequency, duty, cycles) the current PWM entry, its first cycle starting `at`."""
        self.pwm_frequency, self.pwm_duty_percent, self.pwm_cycles = float(frequency), float(duty), cycles
        self.pwm_ends_at = at + cycles / frequency if cycles else None

    def as_dict(self) -> dict[str, Any]:
        return {
            "claim": self.claim, "flags": self.flags, "level": self.level,
            "pwm_frequency": self.pwm_frequency, "pwm_duty_percent": self.pwm_duty_percent,
            "pwm_cycles": self.pwm_cycles, "pwm_queued": len(self.pwm_queue),
            "servo_pulse_us": self.servo_pulse_us, "servo_frequency": self.servo_frequency,
            "duty_fraction": self.duty_fraction,
        }


class FakeCallback:
    """What `lgpio.callback()` returns: `cancel()`, `tally()`, `reset_tally()`."""

    def __init__(self, fake: FakeLgpio, chip: int, gpio: int, edge: int,
                 func: Callable[[int, int, int, int], None] | None) -> None:
        self._fake = fake
        self.chip = chip
        self.gpio = gpio
        self.edge = edge
        self.func = func
        self.count = 0

    def _fire(self, level: int, tick_ns: int) -> None:
        self.count += 1
        if self.func is not None:
            self.func(self.chip, self.gpio, level, tick_ns)

    def cancel(self) -> None:
        """Stop receiving alerts; idempotent."""
        self._fake._remove_callback(self)

    def tally(self) -> int:
        return self.count

    def reset_tally(self) -> None:
        self.count = 0


@dataclass
class _Delivery:
    edges: list[tuple[int, int, int, int]] = field(default_factory=list)  # chip, gpio, level, ns
    done: threading.Event | None = None


class FakeLgpio:
    """Stands in for the `lgpio` module; see the module docstring for what it simulates.

    `chips` maps a gpiochip number to its number of lines (default: chip 0 with the Pi 5's 54);
    opening another chip fails as lgpio does when /dev/gpiochipN is missing or not permitted.
    """

    error = error
    LOW, HIGH, TIMEOUT = LOW, HIGH, TIMEOUT
    SET_ACTIVE_LOW, SET_OPEN_DRAIN, SET_OPEN_SOURCE = SET_ACTIVE_LOW, SET_OPEN_DRAIN, SET_OPEN_SOURCE
    SET_PULL_UP, SET_PULL_DOWN, SET_PULL_NONE = SET_PULL_UP, SET_PULL_DOWN, SET_PULL_NONE
    RISING_EDGE, FALLING_EDGE, BOTH_EDGES = RISING_EDGE, FALLING_EDGE, BOTH_EDGES
    TX_PWM, TX_WAVE = TX_PWM, TX_WAVE

    def __init__(self, chips: dict[int, int] | None = None, *, start_ns: int = 1_000_000_000,
                 state_file: str | os.PathLike[str] | None = None) -> None:
        self.chips = dict(chips) if chips is not None else {0: PI5_LINES}
        self.calls: list[tuple[str, tuple[Any, ...]]] = []
        self.lines: dict[tuple[int, int], LineState] = {}
        self.sonars: dict[tuple[int, int], FakeHCSR04] = {}
        self.open_handles: dict[int, int] = {}  # handle & 0xffff -> chip
        self._next_handle = 0
        self._ns = start_ns
        self._callbacks: list[FakeCallback] = []
        self._lock = threading.RLock()
        self._state_file = Path(state_file) if state_file else None
        self._deliveries: queue.Queue[_Delivery | None] = queue.Queue()
        self._worker: threading.Thread | None = None
        self._tx_wake = threading.Condition(self._lock)
        self._tx_thread: threading.Thread | None = None
        self._closed = False
        self._write_state()

    # --- helpers for tests -------------------------------------------------------------------

    def attach_hcsr04(self, trigger: int, echo: int, distance_cm: float | None = 100.0, *,
                      chip: int = 0, no_echo: str = "pulse") -> FakeHCSR04:
        """Simulate an HC-SR04 wired to `trigger`/`echo`; returns it so a test can move the target."""
        if no_echo not in ("pulse", "silent"):
            raise ValueError("no_echo is 'pulse' or 'silent'")
        sonar = FakeHCSR04(trigger, echo, distance_cm, no_echo)
        with self._lock:
            self.sonars[(chip, trigger)] = sonar
        return sonar

    def advance_ns(self, nanoseconds: int) -> None:
        """Let virtual time pass."""
        with self._lock:
            self._ns += nanoseconds

    def set_input(self, gpio: int, level: int, *, chip: int = 0) -> None:
        """Drive a line from outside (a button, a sensor); alert-claimed lines report the edge."""
        with self._lock:
            self._ns += 1000
            edges = self._change(chip, gpio, level)
        self._deliver(_Delivery(edges))

    def line(self, gpio: int, chip: int = 0) -> LineState:
        """The state of one line (created on first use)."""
        with self._lock:
            return self._line(chip, gpio)

    def state(self) -> dict[str, Any]:
        """JSON-able snapshot of the open handles and every line touched so far."""
        with self._lock:
            return {
                "open_handles": len(self.open_handles),
                "lines": {f"{chip}:{gpio}": line.as_dict()
                          for (chip, gpio), line in sorted(self.lines.items())},
            }

    def calls_named(self, name: str) -> list[tuple[Any, ...]]:
        """The argument tuples of every recorded call of function `name`."""
        with self._lock:
            return [args for method, args in self.calls if method == name]

    def wait_idle(self, timeout: float = 2.0) -> bool:
        """Wait until every queued alert delivery ran; True when idle in time."""
        done = threading.Event()
        self._deliver(_Delivery(done=done))
        return done.wait(timeout)

    def shutdown(self) -> None:
        """End the alert and TX threads (lgpio's live as long as the process; tests end theirs)."""
        with self._lock:
            worker, self._worker = self._worker, None
            tx, self._tx_thread = self._tx_thread, None
            self._closed = True
            self._tx_wake.notify_all()
        if worker is not None:
            self._deliveries.put(None)
        for thread in (worker, tx):
            if thread is not None and thread is not threading.current_thread():
                thread.join(timeout=2.0)

    # --- lgpio API -----------------------------------------------------------------------------

    def gpiochip_open(self, gpiochip: int) -> int:
        self._record("gpiochip_open", gpiochip)
        with self._lock:
            if gpiochip not in self.chips:
                raise _fail(CANNOT_OPEN_CHIP)
            self._next_handle += 1
            self.open_handles[self._next_handle] = gpiochip
            return self._next_handle | (gpiochip << 16)

    def gpiochip_close(self, handle: int) -> int:
        self._record("gpiochip_close", handle)
        with self._lock:
            chip = self._chip_of(handle)
            for (line_chip, _gpio), line in self.lines.items():
                if line_chip == chip and line.handle == handle & 0xFFFF:
                    self._free(line)
            del self.open_handles[handle & 0xFFFF]
        self._write_state()
        return OKAY

    def gpio_claim_input(self, handle: int, gpio: int, lFlags: int = 0) -> int:
        self._record("gpio_claim_input", handle, gpio, lFlags)
        with self._lock:
            line = self._claimable(handle, gpio)
            line.stop_tx()
            line.claim, line.handle, line.flags, line.edges = "input", handle & 0xFFFF, lFlags, 0
            self._apply_pull(line)
        self._write_state()
        return OKAY

    def gpio_claim_output(self, handle: int, gpio: int, level: int = 0, lFlags: int = 0) -> int:
        self._record("gpio_claim_output", handle, gpio, level, lFlags)
        with self._lock:
            line = self._claimable(handle, gpio)
            line.stop_tx()
            line.claim, line.handle, line.flags, line.edges = "output", handle & 0xFFFF, lFlags, 0
            line.level = 1 if level else 0
        self._write_state()
        return OKAY

    def gpio_claim_alert(self, handle: int, gpio: int, eFlags: int, lFlags: int = 0,
                         notify_handle: int | None = None) -> int:
        self._record("gpio_claim_alert", handle, gpio, eFlags, lFlags)
        with self._lock:
            line = self._claimable(handle, gpio)
            line.stop_tx()
            line.claim, line.handle, line.flags, line.edges = "alert", handle & 0xFFFF, lFlags, eFlags
            self._apply_pull(line)
        self._write_state()
        return OKAY

    def gpio_free(self, handle: int, gpio: int) -> int:
        self._record("gpio_free", handle, gpio)
        with self._lock:
            line = self._owned(handle, gpio)
            self._free(line)
        self._write_state()
        return OKAY

    def gpio_get_mode(self, handle: int, gpio: int) -> int:
        self._record("gpio_get_mode", handle, gpio)
        with self._lock:
            chip = self._chip_of(handle)
            line = self._line(chip, self._checked_gpio(chip, gpio))
            mine = line.handle == handle & 0xFFFF
            lg_bits = {"input": 1 << 8, "output": 1 << 9, "alert": 1 << 10}.get(line.claim, 0)
            kernel = (1 if line.claim != "free" else 0) | (2 if line.claim == "output" else 0)
            return kernel | (line.flags & 0xFC) | (lg_bits if mine else 0)

    def gpio_read(self, handle: int, gpio: int) -> int:
        self._record("gpio_read", handle, gpio)
        with self._lock:
            return self._owned(handle, gpio).level

    def gpio_write(self, handle: int, gpio: int, level: int) -> int:
        """Set an output's level. Like lgpio, this does not end PWM or servo pulses on the line."""
        self._record("gpio_write", handle, gpio, level)
        with self._lock:
            line = self._owned(handle, gpio)
            if line.claim != "output":
                raise _fail(GPIO_NOT_AN_OUTPUT)
            self._ns += 1000
            chip = self._chip_of(handle)
            was = line.level
            line.level = 1 if level else 0
            sonar = self.sonars.get((chip, gpio))
            edges = self._ping(chip, sonar) if sonar is not None and was == 1 and line.level == 0 else []
        self._write_state()
        self._deliver(_Delivery(edges))
        return OKAY

    def tx_pwm(self, handle: int, gpio: int, pwm_frequency: float, pwm_duty_cycle: float,
               pulse_offset: int = 0, pulse_cycles: int = 0) -> int:
        """Software PWM: frequency 0 (off) or 0.1..10000 Hz, duty 0..100 %, `pulse_cycles` cycles
        (0: endless); queued behind a running entry (see the module docstring); returns the room
        left in the line's queue."""
        self._record("tx_pwm", handle, gpio, pwm_frequency, pwm_duty_cycle, pulse_offset, pulse_cycles)
        with self._lock:
            line = self._output(handle, gpio)
            if pwm_frequency and not 0.1 <= pwm_frequency <= 10000:
                raise _fail(BAD_PWM_FREQ)
            if not 0 <= pwm_duty_cycle <= 100:
                raise _fail(BAD_PWM_DUTY)
            cycles = max(0, int(pulse_cycles))
            if not pwm_frequency:  # off: the entry ends where it is, the level is not written
                line.stop_tx()
            elif not line.pwm_frequency:
                line.servo_pulse_us = line.servo_frequency = 0
                line.start_pwm(pwm_frequency, pwm_duty_cycle, cycles, time.monotonic())
            else:
                if line.pwm_queue and line.pwm_queue[-1][2] == 0:
                    line.pwm_queue.pop()  # lgpio drops a pending endless entry
                if 1 + len(line.pwm_queue) >= TX_BUF:
                    raise _fail(TX_QUEUE_FULL)
                line.pwm_queue.append((float(pwm_frequency), float(pwm_duty_cycle), cycles))
                if not line.pwm_cycles:  # an endless current entry gives way (at its cycle's end)
                    frequency, duty, next_cycles = line.pwm_queue.pop(0)
                    line.start_pwm(frequency, duty, next_cycles, time.monotonic())
            room = TX_BUF - (1 + len(line.pwm_queue)) if line.pwm_frequency else TX_BUF
            self._tx_wake.notify_all()
            self._ensure_tx_thread()
        self._write_state()
        return room

    def tx_room(self, handle: int, gpio: int, kind: int) -> int:
        """Free entries in the line's PWM queue (`TX_BUF` when no PWM runs)."""
        self._record("tx_room", handle, gpio, kind)
        if kind not in (TX_PWM, TX_WAVE):
            raise _fail(BAD_TX_TYPE)
        with self._lock:
            line = self._owned(handle, gpio)
            return TX_BUF - (1 + len(line.pwm_queue)) if line.pwm_frequency else TX_BUF

    def tx_servo(self, handle: int, gpio: int, pulse_width: int, servo_frequency: int = 50,
                 pulse_offset: int = 0, pulse_cycles: int = 0) -> int:
        """Servo pulses: width 0 (off) or 500..2500 µs at 40..500 Hz; returns queue room."""
        self._record("tx_servo", handle, gpio, pulse_width, servo_frequency, pulse_offset, pulse_cycles)
        with self._lock:
            line = self._output(handle, gpio)
            if pulse_width and not 500 <= pulse_width <= 2500:
                raise _fail(BAD_SERVO_WIDTH)
            if not 40 <= servo_frequency <= 500:
                raise _fail(BAD_SERVO_FREQ)
            line.stop_tx()
            if pulse_width:
                line.servo_pulse_us, line.servo_frequency = int(pulse_width), int(servo_frequency)
        self._write_state()
        return 1

    def tx_busy(self, handle: int, gpio: int, kind: int) -> int:
        """1 while PWM (`TX_PWM`) or servo pulses run on the line."""
        self._record("tx_busy", handle, gpio, kind)
        if kind not in (TX_PWM, TX_WAVE):
            raise _fail(BAD_TX_TYPE)
        with self._lock:
            line = self._output(handle, gpio)
            return int(bool(line.pwm_frequency or line.servo_pulse_us))

    def callback(self, handle: int, gpio: int, edge: int = RISING_EDGE,
                 func: Callable[[int, int, int, int], None] | None = None) -> FakeCallback:
        """Call `func(chip, gpio, level, timestamp_ns)` on alerts of `gpio` (on a separate thread)."""
        self._record("callback", handle, gpio, edge)
        cb = FakeCallback(self, handle >> 16, gpio, edge, func)
        with self._lock:
            self._callbacks.append(cb)
        return cb

    def error_text(self, errnum: int) -> str:
        return error_text(errnum)

    # --- internals ---------------------------------------------------------------------------

    def _record(self, name: str, *args: Any) -> None:
        with self._lock:
            self.calls.append((name, args))

    def _chip_of(self, handle: int) -> int:
        chip = self.open_handles.get(handle & 0xFFFF)
        if chip is None or chip != handle >> 16:
            raise _fail(BAD_HANDLE)
        return chip

    def _checked_gpio(self, chip: int, gpio: int) -> int:
        if not isinstance(gpio, int) or not 0 <= gpio < self.chips[chip]:
            raise _fail(BAD_GPIO_NUMBER)
        return gpio

    def _line(self, chip: int, gpio: int) -> LineState:
        line = self.lines.get((chip, gpio))
        if line is None:
            line = self.lines[(chip, gpio)] = LineState()
        return line

    def _claimable(self, handle: int, gpio: int) -> LineState:
        chip = self._chip_of(handle)
        line = self._line(chip, self._checked_gpio(chip, gpio))
        if line.claim != "free" and line.handle != handle & 0xFFFF:
            raise _fail(GPIO_BUSY)
        return line

    def _owned(self, handle: int, gpio: int) -> LineState:
        chip = self._chip_of(handle)
        line = self._line(chip, self._checked_gpio(chip, gpio))
        if line.claim == "free" or line.handle != handle & 0xFFFF:
            raise _fail(GPIO_NOT_ALLOCATED)
        return line

    def _output(self, handle: int, gpio: int) -> LineState:
        line = self._owned(handle, gpio)
        if line.claim != "output":
            raise _fail(GPIO_NOT_AN_OUTPUT)
        return line

    @staticmethod
    def _apply_pull(line: LineState) -> None:
        if line.flags & SET_PULL_UP:
            line.level = 1
        elif line.flags & SET_PULL_DOWN:
            line.level = 0

    @staticmethod
    def _free(line: LineState) -> None:
        line.stop_tx()
        line.claim, line.handle, line.flags, line.edges = "free", None, 0, 0

    def _change(self, chip: int, gpio: int, level: int) -> list[tuple[int, int, int, int]]:
        """Set a line's level; the alert edges it causes (caller holds the lock)."""
        line = self._line(chip, gpio)
        if line.level == level:
            return []
        line.level = level
        wanted = RISING_EDGE if level else FALLING_EDGE
        if line.claim == "alert" and line.edges & wanted:
            return [(chip, gpio, level, self._ns)]
        return []

    def _ping(self, chip: int, sonar: FakeHCSR04) -> list[tuple[int, int, int, int]]:
        sonar.pings += 1
        self._ns += sonar.echo_delay_us * 1000
        if sonar.distance_cm is None and sonar.no_echo == "silent":
            return []
        width_us = 38_000 if sonar.distance_cm is None else round(max(0.0, sonar.distance_cm) * US_PER_CM)
        edges = self._change(chip, sonar.echo, 1)
        self._ns += width_us * 1000
        return edges + self._change(chip, sonar.echo, 0)

    def _ensure_tx_thread(self) -> None:
        """Start the TX thread once (caller holds the lock)."""
        if self._tx_thread is None and not self._closed:
            self._tx_thread = threading.Thread(target=self._run_tx, name="fake-lgpio-tx", daemon=True)
            self._tx_thread.start()

    def _run_tx(self) -> None:
        """End finite PWM entries when their cycles are done: the next queued one starts, or the
        line is written low and PWM ends (lgpio's TX thread)."""
        with self._lock:
            while not self._closed:
                now = time.monotonic()
                changed = False
                for line in self.lines.values():
                    while line.pwm_ends_at is not None and line.pwm_ends_at <= now:
                        ended = line.pwm_ends_at
                        if line.pwm_queue:
                            frequency, duty, cycles = line.pwm_queue.pop(0)
                            line.start_pwm(frequency, duty, cycles, ended)
                        else:
                            line.stop_tx()
                            line.level = 0  # the TX thread writes the line low after the last cycle
                        changed = True
                if changed:
                    self._write_state()
                ends = [line.pwm_ends_at for line in self.lines.values() if line.pwm_ends_at is not None]
                self._tx_wake.wait(max(0.0, min(ends) - now) if ends else None)

    def _remove_callback(self, cb: FakeCallback) -> None:
        with self._lock, contextlib.suppress(ValueError):
            self._callbacks.remove(cb)

    def _deliver(self, delivery: _Delivery) -> None:
        if not delivery.edges and delivery.done is None:
            return
        with self._lock:
            if self._worker is None:
                self._worker = threading.Thread(target=self._run_callbacks, name="fake-lgpio-alerts",
                                                daemon=True)
                self._worker.start()
        self._deliveries.put(delivery)

    def _run_callbacks(self) -> None:
        while True:
            delivery = self._deliveries.get()
            if delivery is None:
                return
            for chip, gpio, level, ns in delivery.edges:
                with self._lock:
                    targets = [cb for cb in self._callbacks if cb.chip == chip and cb.gpio == gpio]
                for cb in targets:
                    cb._fire(level, ns)
            if delivery.done is not None:
                delivery.done.set()

    def _write_state(self) -> None:
        if self._state_file is None:
            return
        with self._lock:
            tmp = self._state_file.with_suffix(self._state_file.suffix + ".tmp")
            tmp.write_text(json.dumps(self.state()), encoding="utf-8")
            os.replace(tmp, self._state_file)
