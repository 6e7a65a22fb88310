"""`driver: auto`: pick the GPIO backend this machine has, and say which and why.

In order: a fake asked for by the environment (`UMLBOT_FAKE_LGPIO`, `UMLBOT_FAKE_PIGPIO`); a
Raspberry Pi 5 (its device-tree model names it) → `lgpio`, since pigpio cannot drive the Pi 5's
RP1 chip; a pigpio daemon answering at `PIGPIO_ADDR:PIGPIO_PORT` (default localhost:8888) →
`pigpio`; any /dev/gpiochip* → `lgpio`. Nothing of these → `DriverError` naming what was looked for.
"""

from __future__ import annotations

import glob
import os
import re
import socket
import threading
from dataclasses import dataclass
from pathlib import Path

from umlbot.base.errors import DriverError
from umlbot.base.logs import get_logger

log = get_logger("umlbot.driver.auto")

MODEL_FILE = Path("/proc/device-tree/model")
PI5_MODEL = re.compile(r"Raspberry Pi (5|500)\b|Compute Module 5")

_lock = threading.Lock()
_chosen: tuple[str, str] | None = None


@dataclass(frozen=True)
class Machine:
    """What `choose` looks at (gathered by `probe`, given directly by tests)."""

    model: str = ""
    pigpiod: str | None = None  # "host:port" where a pigpio daemon answered
    gpiochips: tuple[str, ...] = ()
    fake: str | None = None  # "lgpio" or "pigpio" when the environment asks for a fake


def choose(machine: Machine) -> tuple[str, str]:
    """The driver for `machine` and the reason, e.g. ``("lgpio", "Raspberry Pi 5 Model B Rev 1.0")``."""
    if machine.fake is not None:
        return machine.fake, f"UMLBOT_FAKE_{machine.fake.upper()} is set"
    if PI5_MODEL.search(machine.model):
        return "lgpio", f"{machine.model} (pigpio does not support the Pi 5)"
    if machine.pigpiod is not None:
        return "pigpio", f"a pigpio daemon answers at {machine.pigpiod}"
    if machine.gpiochips:
        return "lgpio", f"no pigpio daemon; {machine.gpiochips[0]} is there"
    raise DriverError(
        "driver auto found no GPIO backend: not a Raspberry Pi 5, no pigpio daemon at "
        f"{_pigpio_address_text()} and no /dev/gpiochip*; on a machine without GPIO use --driver mock or sim"
    )


def _pigpio_address() -> tuple[str, int]:
    return (os.environ.get("PIGPIO_ADDR") or "localhost", int(os.environ.get("PIGPIO_PORT") or 8888))


def _pigpio_address_text() -> str:
    host, port = _pigpio_address()
    return f"{host}:{port}"


def _env_flag(name: str) -> bool:
    return os.environ.get(name, "").strip().lower() in ("1", "true", "yes", "on")


def probe(timeout_s: float = 0.3) -> Machine:
    """Look at this machine: device-tree model, a pigpio daemon, gpiochip devices, fake requests."""
    fake = next((name for name in ("lgpio", "pigpio") if _env_flag(f"UMLBOT_FAKE_{name.upper()}")), None)
    try:
        model = MODEL_FILE.read_text(encoding="utf-8", errors="replace").strip("\0\n ")
    except OSError:
        model = ""
    pigpiod = None
    if not PI5_MODEL.search(model) and fake is None:
        try:
            with socket.create_connection(_pigpio_address(), timeout=timeout_s):
                pigpiod = _pigpio_address_text()
        except OSError:
            pass
    return Machine(model, pigpiod, tuple(sorted(glob.glob("/dev/gpiochip*"))), fake)


def auto_driver() -> str:
    """The driver `auto` stands for on this machine; chosen once per process and logged."""
    global _chosen
    with _lock:
        if _chosen is None:
            _chosen = choose(probe())
            log.info("driver_auto", chose=_chosen[0], because=_chosen[1])
        return _chosen[0]


def forget() -> None:
    """Choose again on the next `auto_driver()` (tests)."""
    global _chosen
    with _lock:
        _chosen = None
