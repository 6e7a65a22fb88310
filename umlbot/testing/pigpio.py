"""A fake `pigpio.pi`: the daemon's Python API without a Raspberry Pi, for tests and demos.

`FakePi` has the method names, argument conventions, return values and error behaviour of
`pigpio.pi` for what umlbot's drivers use (modes, levels, software PWM, servo pulses, triggers,
edge callbacks, ticks), records every call in `calls`, and can simulate HC-SR04 range finders:
`attach_hcsr04(trigger, echo, distance_cm)` makes every `gpio_trigger` on `trigger` produce a
rising and a falling edge on `echo` whose tick difference is `distance_cm * 58` µs, delivered to
the registered callbacks on a separate thread as pigpio does.

Ticks are virtual: they are 32-bit microsecond counters (wrapping at 2**32 like pigpio's) that
advance only by the simulated durations (trigger pulse, echo delay and pulse) and by
`advance_ticks()`, so tests are deterministic; `set_tick()` puts the counter just before the wrap.

`state()` returns every pin's mode, level, PWM and servo settings; with `state_file` the same JSON
is rewritten after every output change, so a test can read the final pin state of a service
running in another process (see `umlbot.services.pins.pigpio`).

Scripts run as in the daemon (`store_script`, `run_script`, `update_script`, `script_status`,
`stop_script`, `delete_script`): each on its own thread, with pigpio's parameters p0..p9 (which
`update_script` changes while it runs), variables v0..v149, accumulator and flag, and the
commands TAG, JMP, JZ, JNZ, JP, JM, LD, LDA, STA, ADD, SUB, CMP, DCR, INR, MILS (real
milliseconds), W, PWM and HALT; any other command is refused as pigpio refuses an illegal one. A
script outlives the client connection (`stop()`, `connected = False`), as it does in pigpiod.
"""

from __future__ import annotations

import contextlib
import json
import os
import queue
import threading
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

# Constants with pigpio's values.
INPUT = 0
OUTPUT = 1
PUD_OFF = 0
PUD_DOWN = 1
PUD_UP = 2
RISING_EDGE = 0
FALLING_EDGE = 1
EITHER_EDGE = 2
TIMEOUT = 2  # level passed to callbacks on a watchdog time-out
TICK_WRAP = 1 << 32

#: Frequencies pigpio offers at its default 5 µs sample rate, highest first.
PWM_FREQUENCIES: tuple[int, ...] = (
    8000, 4000, 2000, 1600, 1000, 800, 500, 400, 320, 250, 200, 160, 100, 80, 50, 40, 20, 10,
)
DEFAULT_PWM_RANGE = 255
DEFAULT_PWM_FREQUENCY = 800
SPEED_OF_SOUND_US_PER_CM = 58.0  # round trip, as the HC-SR04 datasheet states


# Script states and limits, with pigpio's values.
PI_SCRIPT_INITING = 0
PI_SCRIPT_HALTED = 1
PI_SCRIPT_RUNNING = 2
PI_SCRIPT_WAITING = 3
PI_SCRIPT_FAILED = 4
MAX_SCRIPTS = 32
MAX_SCRIPT_PARAMS = 10
MAX_SCRIPT_VARS = 150
MAX_MILS_DELAY = 60000

#: the script commands the fake runs -> their arguments: `val` (number, vN or pN), `reg` (vN or
#: pN), `tag` (a number naming a TAG)
SCRIPT_COMMANDS: dict[str, tuple[str, ...]] = {
    "TAG": ("tag",), "JMP": ("tag",), "JZ": ("tag",), "JNZ": ("tag",), "JP": ("tag",),
    "JM": ("tag",), "LD": ("reg", "val"), "LDA": ("val",), "STA": ("reg",), "ADD": ("val",),
    "SUB": ("val",), "CMP": ("val",), "DCR": ("reg",), "INR": ("reg",), "MILS": ("val",),
    "W": ("val", "val"), "PWM": ("val", "val"), "HALT": (),
}


class error(Exception):
    """What `pigpio.pi` methods raise on a bad argument or a lost daemon (`pigpio.error`)."""


def tickDiff(t1: int, t2: int) -> int:
    """Microseconds from tick t1 to tick t2, correct across the 32-bit wrap (as `pigpio.tickDiff`)."""
    diff = t2 - t1
    if diff < 0:
        diff += TICK_WRAP
    return diff


@dataclass
class PinState:
    """Everything the fake knows about one GPIO."""

    mode: int = INPUT
    level: int = 0
    pull: int = PUD_OFF
    pwm_dutycycle: int = 0
    pwm_range: int = DEFAULT_PWM_RANGE
    pwm_frequency: int = DEFAULT_PWM_FREQUENCY
    servo_pulsewidth: int = 0

    @property
    def pwm_active(self) -> bool:
        return self.pwm_dutycycle > 0

    @property
    def duty_fraction(self) -> float:
        """The PWM output as a fraction 0..1 (1.0 for a pin written high without PWM)."""
        if self.pwm_dutycycle:
            return self.pwm_dutycycle / self.pwm_range
        return float(self.level) if self.mode == OUTPUT and not self.servo_pulsewidth else 0.0

    def as_dict(self) -> dict[str, Any]:
        return {
            "mode": "output" if self.mode == OUTPUT else "input",
            "level": self.level,
            "pull": self.pull,
            "pwm_dutycycle": self.pwm_dutycycle,
            "pwm_range": self.pwm_range,
            "pwm_frequency": self.pwm_frequency,
            "servo_pulsewidth": self.servo_pulsewidth,
            "duty_fraction": self.duty_fraction,
        }


@dataclass
class FakeHCSR04:
    """A simulated HC-SR04: the distance it sees (None = nothing in range) and how it answers."""

    trigger: int
    echo: int
    distance_cm: float | None = 100.0
    #: "silent" = no echo edge at all; "pulse" = a 38 ms high pulse as many modules give.
    no_echo: str = "pulse"
    echo_delay_us: int = 450  # the module's burst time between trigger and echo rising
    pings: int = 0


class FakeCallback:
    """What `pi.callback()` returns: `cancel()` and `tally()` as in pigpio."""

    def __init__(self, pi: FakePi, gpio: int, edge: int, func: Callable[[int, int, int], None] | None):
        self._pi = pi
        self.gpio = gpio
        self.edge = edge
        self.func = func
        self._count = 0
        self.cancelled = False

    def _fire(self, gpio: int, level: int, tick: int) -> None:
        if self.cancelled:
            return
        if self.edge == RISING_EDGE and level != 1:
            return
        if self.edge == FALLING_EDGE and level != 0:
            return
        self._count += 1
        if self.func is not None:
            self.func(gpio, level, tick)

    def cancel(self) -> None:
        """Stop receiving edges; idempotent."""
        self.cancelled = True
        self._pi._remove_callback(self)

    def tally(self) -> int:
        """How many matching edges were seen."""
        return self._count

    def reset_tally(self) -> None:
        self._count = 0


@dataclass
class _Edge:
    gpio: int
    level: int
    tick: int


@dataclass
class _Delivery:
    edges: list[_Edge] = field(default_factory=list)
    done: threading.Event | None = None


Operand = tuple[str, int]  # ("num" | "var" | "par", value or register number)


@dataclass
class _Script:
    """One stored script, as pigpiod keeps it."""

    ident: int
    instructions: list[tuple[str, tuple[Operand, ...]]]
    tags: dict[int, int]
    params: list[int] = field(default_factory=lambda: [0] * MAX_SCRIPT_PARAMS)
    variables: list[int] = field(default_factory=lambda: [0] * MAX_SCRIPT_VARS)
    run_state: int = PI_SCRIPT_INITING
    request: str = "halt"  # run, halt
    runs: int = 0  # run_script calls: each wakes a halted script once
    dying: bool = False
    cond: threading.Condition = field(default_factory=threading.Condition)
    wake: threading.Event = field(default_factory=threading.Event)  # delete cuts a MILS short


def parse_script(text: str) -> tuple[list[tuple[str, tuple[Operand, ...]]], dict[int, int]]:
    """The instructions and tags of a script; `error` with pigpio's message when it is invalid."""
    tokens = text.split()
    instructions: list[tuple[str, tuple[Operand, ...]]] = []
    tags: dict[int, int] = {}
    i = 0
    while i < len(tokens):
        name = tokens[i].upper()
        kinds = SCRIPT_COMMANDS.get(name)
        if kinds is None:
            raise error("illegal script command")
        args = tokens[i + 1:i + 1 + len(kinds)]
        if len(args) < len(kinds):
            raise error("invalid script")
        operands = tuple(_operand(token, kind) for token, kind in zip(args, kinds, strict=True))
        if name == "TAG":
            if operands[0][1] in tags:
                raise error("script has duplicate tag")
            tags[operands[0][1]] = len(instructions)
        instructions.append((name, operands))
        i += 1 + len(kinds)
    for name, operands in instructions:
        if SCRIPT_COMMANDS[name] == ("tag",) and name != "TAG" and operands[0][1] not in tags:
            raise error("script has unresolved tag")
    return instructions, tags


def _operand(token: str, kind: str) -> Operand:
    lower = token.lower()
    if lower[:1] in ("v", "p") and lower[1:].isdigit():
        if kind == "tag":
            raise error("invalid script")
        number, register = int(lower[1:]), ("var" if lower[0] == "v" else "par")
        if register == "var" and number >= MAX_SCRIPT_VARS:
            raise error("script variable id not 0-149")
        if register == "par" and number >= MAX_SCRIPT_PARAMS:
            raise error("script parameter id not 0-9")
        return register, number
    if kind == "reg":
        raise error("invalid script")
    try:
        return "num", int(token, 0)
    except ValueError:
        raise error("invalid script") from None


class FakePi:
    """Stands in for `pigpio.pi(host, port)`; see the module docstring for what it simulates."""

    def __init__(
        self,
        host: str = "localhost",
        port: int = 8888,
        *,
        connected: bool = True,
        start_tick: int = 0,
        state_file: str | os.PathLike[str] | None = None,
    ) -> None:
        self.host = host
        self.port = port
        self.connected = connected
        self.calls: list[tuple[str, tuple[Any, ...]]] = []
        self.pins: dict[int, PinState] = {}
        self.sonars: dict[int, FakeHCSR04] = {}
        self.stopped = False
        self._tick = start_tick % TICK_WRAP
        self._callbacks: list[FakeCallback] = []
        self._lock = threading.RLock()
        self._state_file = Path(state_file) if state_file else None
        self._deliveries: queue.Queue[_Delivery | None] = queue.Queue()
        self._worker: threading.Thread | None = None
        self.scripts: dict[int, _Script] = {}
        self._write_state()

    # --- helpers for tests -------------------------------------------------------------------

    def attach_hcsr04(
        self, trigger: int, echo: int, distance_cm: float | None = 100.0, *, no_echo: str = "pulse"
    ) -> FakeHCSR04:
        """Simulate an HC-SR04 wired to `trigger`/`echo`; returns it so a test can move the target."""
        if no_echo not in ("pulse", "silent"):
            raise ValueError("no_echo is 'pulse' or 'silent'")
        sonar = FakeHCSR04(trigger, echo, distance_cm, no_echo)
        with self._lock:
            self.sonars[trigger] = sonar
        return sonar

    def set_tick(self, tick: int) -> None:
        """Set the virtual tick counter (e.g. 2**32 - 100 to cross the wrap in the next echo)."""
        with self._lock:
            self._tick = tick % TICK_WRAP

    def advance_ticks(self, microseconds: int) -> None:
        """Let virtual time pass."""
        with self._lock:
            self._tick = (self._tick + microseconds) % TICK_WRAP

    def set_input(self, gpio: int, level: int) -> None:
        """Drive an input from outside (a button, a sensor); fires the matching callbacks."""
        with self._lock:
            pin = self._pin(gpio)
            if pin.level == level:
                return
            pin.level = level
            self._tick = (self._tick + 1) % TICK_WRAP
            edge = _Edge(gpio, level, self._tick)
        self._deliver(_Delivery([edge]))

    def pin(self, gpio: int) -> PinState:
        """The state of one pin (created on first use, as every GPIO exists)."""
        with self._lock:
            return self._pin(gpio)

    def state(self) -> dict[str, Any]:
        """JSON-able snapshot: connection and every pin touched so far."""
        with self._lock:
            return {
                "connected": self.connected,
                "stopped": self.stopped,
                "tick": self._tick,
                "pins": {str(g): p.as_dict() for g, p in sorted(self.pins.items())},
            }

    def calls_named(self, name: str) -> list[tuple[Any, ...]]:
        """The argument tuples of every recorded call of method `name`."""
        with self._lock:
            return [args for method, args in self.calls if method == name]

    def wait_idle(self, timeout: float = 2.0) -> bool:
        """Wait until every queued callback delivery ran; True when idle in time."""
        done = threading.Event()
        self._deliver(_Delivery(done=done))
        return done.wait(timeout)

    # --- pigpio.pi API -----------------------------------------------------------------------

    def set_mode(self, gpio: int, mode: int) -> int:
        self._record("set_mode", gpio, mode)
        self._check_gpio(gpio)
        if mode not in (INPUT, OUTPUT, 2, 3, 4, 5, 6, 7):
            raise error("GPIO mode not 0-7")
        with self._lock:
            pin = self._pin(gpio)
            pin.mode = mode
            if mode == INPUT:
                pin.pwm_dutycycle = 0
                pin.servo_pulsewidth = 0
        self._write_state()
        return 0

    def get_mode(self, gpio: int) -> int:
        self._record("get_mode", gpio)
        self._check_gpio(gpio)
        return self.pin(gpio).mode

    def set_pull_up_down(self, gpio: int, pud: int) -> int:
        self._record("set_pull_up_down", gpio, pud)
        self._check_gpio(gpio)
        if pud not in (PUD_OFF, PUD_DOWN, PUD_UP):
            raise error("GPIO pull-up/down not 0-2")
        with self._lock:
            pin = self._pin(gpio)
            pin.pull = pud
            if pin.mode == INPUT and pud != PUD_OFF:
                pin.level = 1 if pud == PUD_UP else 0
        return 0

    def read(self, gpio: int) -> int:
        self._record("read", gpio)
        self._check_gpio(gpio)
        with self._lock:
            pin = self._pin(gpio)
            if pin.pwm_dutycycle:
                return 1 if pin.pwm_dutycycle >= pin.pwm_range else 0
            return pin.level

    def write(self, gpio: int, level: int) -> int:
        """Set a level; like pigpio this makes the pin an output and ends PWM/servo pulses on it."""
        self._record("write", gpio, level)
        self._check_gpio(gpio)
        if level not in (0, 1):
            raise error("level not 0-1")
        with self._lock:
            pin = self._pin(gpio)
            pin.mode = OUTPUT
            pin.level = level
            pin.pwm_dutycycle = 0
            pin.servo_pulsewidth = 0
        self._write_state()
        return 0

    def set_PWM_dutycycle(self, user_gpio: int, dutycycle: int) -> int:
        self._record("set_PWM_dutycycle", user_gpio, dutycycle)
        self._check_gpio(user_gpio, user=True)
        with self._lock:
            pin = self._pin(user_gpio)
            if not 0 <= dutycycle <= pin.pwm_range:
                raise error("dutycycle not 0-range (0-255)")
            pin.mode = OUTPUT
            pin.servo_pulsewidth = 0
            pin.pwm_dutycycle = int(dutycycle)
            pin.level = 1 if dutycycle >= pin.pwm_range else 0
        self._write_state()
        return 0

    def get_PWM_dutycycle(self, user_gpio: int) -> int:
        self._record("get_PWM_dutycycle", user_gpio)
        self._check_gpio(user_gpio, user=True)
        with self._lock:
            pin = self._pin(user_gpio)
            if not pin.pwm_dutycycle:
                raise error("GPIO is not in use for PWM")
            return pin.pwm_dutycycle

    def set_PWM_range(self, user_gpio: int, range_: int) -> int:
        """Set the duty range (25..40000); returns the real range for the pin's frequency."""
        self._record("set_PWM_range", user_gpio, range_)
        self._check_gpio(user_gpio, user=True)
        if not 25 <= range_ <= 40000:
            raise error("dutycycle range not 25-40000")
        with self._lock:
            pin = self._pin(user_gpio)
            # pigpio rescales a running duty cycle to the new range.
            if pin.pwm_dutycycle:
                pin.pwm_dutycycle = round(pin.pwm_dutycycle * range_ / pin.pwm_range)
            pin.pwm_range = range_
            real = self._real_range(pin.pwm_frequency)
        self._write_state()
        return real

    def get_PWM_range(self, user_gpio: int) -> int:
        self._record("get_PWM_range", user_gpio)
        return self.pin(user_gpio).pwm_range

    def get_PWM_real_range(self, user_gpio: int) -> int:
        self._record("get_PWM_real_range", user_gpio)
        return self._real_range(self.pin(user_gpio).pwm_frequency)

    def set_PWM_frequency(self, user_gpio: int, frequency: int) -> int:
        """Select the nearest frequency pigpio offers; returns it."""
        self._record("set_PWM_frequency", user_gpio, frequency)
        self._check_gpio(user_gpio, user=True)
        if frequency < 0:
            raise error("bad PWM frequency")
        chosen = min(PWM_FREQUENCIES, key=lambda f: (abs(f - frequency), -f))
        with self._lock:
            self._pin(user_gpio).pwm_frequency = chosen
        self._write_state()
        return chosen

    def get_PWM_frequency(self, user_gpio: int) -> int:
        self._record("get_PWM_frequency", user_gpio)
        return self.pin(user_gpio).pwm_frequency

    def set_servo_pulsewidth(self, user_gpio: int, pulsewidth: int) -> int:
        """0 switches pulses off; otherwise 500..2500 µs."""
        self._record("set_servo_pulsewidth", user_gpio, pulsewidth)
        self._check_gpio(user_gpio, user=True)
        if pulsewidth != 0 and not 500 <= pulsewidth <= 2500:
            raise error("pulsewidth not 0 or 500-2500")
        with self._lock:
            pin = self._pin(user_gpio)
            pin.mode = OUTPUT
            pin.pwm_dutycycle = 0
            pin.servo_pulsewidth = int(pulsewidth)
            pin.level = 0
        self._write_state()
        return 0

    def get_servo_pulsewidth(self, user_gpio: int) -> int:
        self._record("get_servo_pulsewidth", user_gpio)
        with self._lock:
            width = self._pin(user_gpio).servo_pulsewidth
        if not width:
            raise error("GPIO is not in use for servo pulses")
        return width

    def gpio_trigger(self, user_gpio: int, pulse_len: int = 10, level: int = 1) -> int:
        """Send a pulse of `pulse_len` µs (1..100); an attached HC-SR04 answers with echo edges."""
        self._record("gpio_trigger", user_gpio, pulse_len, level)
        self._check_gpio(user_gpio, user=True)
        if not 1 <= pulse_len <= 100:
            raise error("trigger pulse length not 1-100")
        if level not in (0, 1):
            raise error("level not 0-1")
        with self._lock:
            pin = self._pin(user_gpio)
            if pin.mode != OUTPUT:
                raise error("GPIO is not an output")  # a real pin would not pulse as an input
            self._tick = (self._tick + pulse_len) % TICK_WRAP
            sonar = self.sonars.get(user_gpio)
            if sonar is None or level != 1:
                return 0
            sonar.pings += 1
            rise = (self._tick + sonar.echo_delay_us) % TICK_WRAP
            if sonar.distance_cm is None:
                if sonar.no_echo == "silent":
                    self._tick = rise
                    return 0
                width = 38_000
            else:
                width = round(max(0.0, sonar.distance_cm) * SPEED_OF_SOUND_US_PER_CM)
            fall = (rise + width) % TICK_WRAP
            self._tick = fall
            edges = [_Edge(sonar.echo, 1, rise), _Edge(sonar.echo, 0, fall)]
            self._pin(sonar.echo).level = 0
        self._deliver(_Delivery(edges))
        return 0

    def callback(
        self, user_gpio: int, edge: int = RISING_EDGE, func: Callable[[int, int, int], None] | None = None
    ) -> FakeCallback:
        """Call `func(gpio, level, tick)` on edges of `user_gpio` (on a separate thread)."""
        self._record("callback", user_gpio, edge)
        self._check_gpio(user_gpio, user=True)
        if edge not in (RISING_EDGE, FALLING_EDGE, EITHER_EDGE):
            raise error("bad edge")
        cb = FakeCallback(self, user_gpio, edge, func)
        with self._lock:
            self._callbacks.append(cb)
        return cb

    # scripts ---------------------------------------------------------------------------------

    def store_script(self, script: str | bytes) -> int:
        """Store a script; returns its id. It is `PI_SCRIPT_INITING` until its thread runs."""
        self._record("store_script", script)
        text = script.decode("utf-8") if isinstance(script, bytes) else script
        instructions, tags = parse_script(text)
        with self._lock:
            free = [i for i in range(MAX_SCRIPTS) if i not in self.scripts]
            if not free:
                raise error("no more room for scripts")
            stored = self.scripts[free[0]] = _Script(free[0], instructions, tags)
        threading.Thread(target=self._run_script_thread, args=(stored,),
                         name=f"fake-pigpio-script-{stored.ident}", daemon=True).start()
        return stored.ident

    def run_script(self, script_id: int, params: list[int] | None = None) -> int:
        """Run a halted script from its start with these parameters (p0..); a running one gets
        the parameters only."""
        self._record("run_script", script_id, params)
        stored = self._script(script_id)
        with stored.cond:
            if stored.run_state == PI_SCRIPT_INITING:
                raise error("script initialising")
            self._set_params(stored, params)
            stored.request = "run"
            stored.runs += 1
            stored.cond.notify_all()
        return 0

    def update_script(self, script_id: int, params: list[int] | None = None) -> int:
        """Change the parameters of a script, running or not."""
        self._record("update_script", script_id, params)
        stored = self._script(script_id)
        with stored.cond:
            self._set_params(stored, params)
        return 0

    def script_status(self, script_id: int) -> tuple[int, tuple[int, ...]]:
        """(run status, the 10 parameters) of a stored script."""
        self._record("script_status", script_id)
        stored = self._script(script_id)
        with stored.cond:
            return stored.run_state, tuple(stored.params)

    def stop_script(self, script_id: int) -> int:
        """Ask a script to halt: it does after the command it is in (a MILS runs to its end)."""
        self._record("stop_script", script_id)
        stored = self._script(script_id)
        with stored.cond:
            stored.request = "halt"
            stored.cond.notify_all()
        return 0

    def delete_script(self, script_id: int) -> int:
        """Halt and forget a script; its id is free again."""
        self._record("delete_script", script_id)
        stored = self._script(script_id)
        with stored.cond:
            stored.request, stored.dying = "halt", True
            stored.wake.set()
            stored.cond.notify_all()
        with self._lock:
            self.scripts.pop(script_id, None)
        return 0

    def _script(self, script_id: int) -> _Script:
        with self._lock:
            stored = self.scripts.get(script_id) if isinstance(script_id, int) else None
        if stored is None:
            raise error("unknown script id")
        return stored

    @staticmethod
    def _set_params(stored: _Script, params: list[int] | None) -> None:
        if params is None:
            return
        if len(params) > MAX_SCRIPT_PARAMS:
            raise error("too many script parameters (> 10)")
        for index, value in enumerate(params):
            if not 0 <= int(value) < 1 << 32:  # pigpio packs them as unsigned 32-bit numbers
                raise error(f"script parameter {value} is not an unsigned 32-bit number")
            stored.params[index] = int(value) - (1 << 32) if value >= 1 << 31 else int(value)

    def _run_script_thread(self, stored: _Script) -> None:
        """pigpiod's script thread: halted until run, then the commands until halted or stopped."""
        seen = 0
        while True:
            with stored.cond:
                stored.run_state = PI_SCRIPT_HALTED
                while stored.runs == seen and not stored.dying:
                    stored.cond.wait()
                if stored.dying:
                    return
                seen = stored.runs
                stored.run_state = PI_SCRIPT_RUNNING
            self._execute(stored)

    def _execute(self, stored: _Script) -> None:
        acc = flag = pc = 0
        while True:
            with stored.cond:
                if stored.request != "run" or stored.run_state != PI_SCRIPT_RUNNING or stored.dying:
                    if stored.request == "halt":
                        stored.run_state = PI_SCRIPT_HALTED
                    return
                name, operands = stored.instructions[pc]
                values = [self._value(stored, operand) for operand in operands]
            if name == "MILS":
                if not 0 <= values[0] <= MAX_MILS_DELAY:
                    acc = flag = -64  # PI_BAD_MILS_DELAY
                else:
                    stored.wake.wait(values[0] / 1000)
                pc += 1
            elif name in ("W", "PWM"):
                acc = flag = self._daemon_output(name, values[0], values[1])
                pc += 1
            else:
                with stored.cond:
                    acc, flag, pc = self._step(stored, name, operands, values, acc, flag, pc)
            with stored.cond:
                if pc >= len(stored.instructions):
                    stored.run_state = PI_SCRIPT_HALTED

    @staticmethod
    def _value(stored: _Script, operand: Operand) -> int:
        kind, number = operand
        if kind == "var":
            return stored.variables[number]
        if kind == "par":
            return stored.params[number]
        return number

    @staticmethod
    def _step(stored: _Script, name: str, operands: tuple[Operand, ...], values: list[int],
              acc: int, flag: int, pc: int) -> tuple[int, int, int]:
        """One command without I/O (caller holds the script's lock): (A, F, PC) after it."""
        if name in ("DCR", "INR", "STA", "LD"):
            kind, number = operands[0]
            registers = stored.variables if kind == "var" else stored.params
            if name == "DCR":
                registers[number] -= 1
                flag = registers[number]
            elif name == "INR":
                registers[number] += 1
                flag = registers[number]
            elif name == "STA":
                registers[number] = acc
            else:
                registers[number] = values[1]
            return acc, flag, pc + 1
        if name == "HALT":
            stored.run_state = PI_SCRIPT_HALTED
            return acc, flag, pc
        jumps = {"JMP": True, "JZ": flag == 0, "JNZ": flag != 0, "JP": flag >= 0, "JM": flag < 0}
        if name in jumps:
            return acc, flag, stored.tags[operands[0][1]] if jumps[name] else pc + 1
        if name == "LDA":
            acc = values[0]
        elif name == "ADD":
            acc = flag = acc + values[0]
        elif name == "SUB":
            acc = flag = acc - values[0]
        elif name == "CMP":
            flag = acc - values[0]
        return acc, flag, pc + 1  # TAG: nothing

    def _daemon_output(self, name: str, gpio: int, value: int) -> int:
        """A script's W or PWM: as the client calls, but inside the daemon (not recorded, and
        whether a client is connected does not matter); pigpio's error number on a bad one."""
        if not 0 <= gpio <= 31:
            return -3  # PI_BAD_USER_GPIO
        with self._lock:
            pin = self._pin(gpio)
            if name == "W":
                if value not in (0, 1):
                    return -5  # PI_BAD_LEVEL
                pin.level = value
                pin.pwm_dutycycle = 0
            else:
                if not 0 <= value <= pin.pwm_range:
                    return -8  # PI_BAD_DUTYCYCLE
                pin.pwm_dutycycle = value
                pin.level = 1 if value >= pin.pwm_range else 0
            pin.mode = OUTPUT
            pin.servo_pulsewidth = 0
        self._write_state()
        return 0

    def get_current_tick(self) -> int:
        self._record("get_current_tick")
        with self._lock:
            return self._tick

    def stop(self) -> None:
        """Release the connection, as `pi.stop()`; idempotent."""
        self._record("stop")
        with self._lock:
            self.stopped = True
            self.connected = False
            worker = self._worker
            self._worker = None
        if worker is not None:
            self._deliveries.put(None)
            if worker is not threading.current_thread():
                worker.join(timeout=2.0)
        self._write_state()

    # --- internals ---------------------------------------------------------------------------

    def _record(self, name: str, *args: Any) -> None:
        with self._lock:
            self.calls.append((name, args))
            if not self.connected and name != "stop":
                raise error(f"{name}: not connected to the pigpio daemon")

    @staticmethod
    def _check_gpio(gpio: int, user: bool = False) -> None:
        top = 31 if user else 53
        if not isinstance(gpio, int) or not 0 <= gpio <= top:
            raise error(f"GPIO not 0-{top}")

    def _pin(self, gpio: int) -> PinState:
        pin = self.pins.get(gpio)
        if pin is None:
            pin = self.pins[gpio] = PinState()
        return pin

    @staticmethod
    def _real_range(frequency: int) -> int:
        return max(1, 200_000 // max(1, frequency))  # 5 µs sample rate

    def _remove_callback(self, cb: FakeCallback) -> None:
        with self._lock, contextlib.suppress(ValueError):
            self._callbacks.remove(cb)

    def _deliver(self, delivery: _Delivery) -> None:
        with self._lock:
            if self._worker is None and not self.stopped:
                self._worker = threading.Thread(
                    target=self._run_callbacks, name="fake-pigpio-cb", daemon=True
                )
                self._worker.start()
        self._deliveries.put(delivery)

    def _run_callbacks(self) -> None:
        while True:
            delivery = self._deliveries.get()
            if delivery is None:
                return
            for edge in delivery.edges:
                with self._lock:
                    targets = [cb for cb in self._callbacks if cb.gpio == edge.gpio]
                for cb in targets:
                    cb._fire(edge.gpio, edge.level, edge.tick)
            if delivery.done is not None:
                delivery.done.set()

    def _write_state(self) -> None:
        if self._state_file is None:
            return
        with self._lock:
            tmp = self._state_file.with_suffix(self._state_file.suffix + ".tmp")
            tmp.write_text(json.dumps(self.state()), encoding="utf-8")
            os.replace(tmp, self._state_file)

