"""One shared gpiochip handle per process through `lgpio`, or the fake `lgpio` for tests.

Only the lgpio drivers use this module, and only here is `lgpio` imported (lazily), so the rest of
umlbot runs on machines without it. lgpio talks to /dev/gpiochipN directly (no daemon): on a
Raspberry Pi 5 the header's GPIOs are lines of the RP1 chip, 0 on current kernels. All drivers of
a process share one handle per chip, reference-counted: the last `release` closes the chip
(which frees every line still claimed through it).

The fake: `install_fake(FakeLgpio())` makes every later `acquire` use that fake (tests in the
same process). For a service in another process set `UMLBOT_FAKE_LGPIO=1` (a fresh `FakeLgpio`
is made on first use) and optionally `UMLBOT_FAKE_LGPIO_STATE=/path/state.json` (the fake
rewrites its line state there after every output change).
"""

from __future__ import annotations

import importlib
import os
import sys
import threading
from typing import TYPE_CHECKING, Any

from umlbot.base.errors import DriverError
from umlbot.base.logs import get_logger

if TYPE_CHECKING:  # the fake is imported only when the environment asks for it (below)
    from umlbot.testing.lgpio import FakeLgpio

log = get_logger("umlbot.lgpio")

FAKE_ENV = "UMLBOT_FAKE_LGPIO"
FAKE_STATE_ENV = "UMLBOT_FAKE_LGPIO_STATE"

_lock = threading.Lock()
_fake: FakeLgpio | None = None
_env_fake: FakeLgpio | None = None
_shared: dict[int, tuple[int, int]] = {}  # chip -> (handle, users)


def install_fake(fake: FakeLgpio | None) -> None:
    """Make `acquire` use `fake` (None: back to the real `lgpio` module or the env-selected fake)."""
    global _fake, _env_fake
    with _lock:
        _fake, _env_fake = fake, None
        _shared.clear()


def env_wants_fake() -> bool:
    """True when `UMLBOT_FAKE_LGPIO` asks for the fake."""
    return os.environ.get(FAKE_ENV, "").strip().lower() in ("1", "true", "yes", "on")


def lgpio_module() -> Any:
    """The `lgpio` module in use: the installed fake, the env-selected fake, or the real one."""
    global _fake, _env_fake
    with _lock:
        if _fake is None and env_wants_fake():
            from umlbot.testing.lgpio import FakeLgpio  # tests only: a robot never loads the fake

            _fake = _env_fake = FakeLgpio(state_file=os.environ.get(FAKE_STATE_ENV) or None)
            log.warning("using the fake lgpio (no hardware)", env=FAKE_ENV)
        if _fake is not None:
            return _fake
    try:
        return importlib.import_module("lgpio")
    except ImportError as exc:
        raise DriverError(missing_lgpio_message()) from exc
    except OSError as exc:  # importing lgpio opens its notification pipe in the working directory
        raise DriverError(
            f"lgpio cannot start ({exc}); it makes its notification pipe (.lgd-nfy*) in the working "
            f"directory {os.getcwd()}, which must be writable"
        ) from exc


def missing_lgpio_message() -> str:
    """What to do when `import lgpio` fails: install it into the Python that runs the service.

    Debian's python3-lgpio goes into the system's Python only; a venv made without
    --system-site-packages (deploy/install.sh's) does not see it, so that is not the advice."""
    python = sys.executable
    return (f"the lgpio Python package is not installed for {python}: install it into that Python with "
            f"`{python} -m pip install 'lgpio>=0.2.2'` (umlbot's `pi` extra, which deploy/install.sh "
            "installs); where PyPI has no lgpio wheel for this Python (lgpio 0.2.2's stop at 3.12), pip "
            "builds it and needs `sudo apt install swig python3-dev liblgpio-dev` first. Debian's "
            "python3-lgpio serves the system's Python only, not a virtual environment. Or use --driver "
            "mock / sim")


def _open(lg: Any, chip: int) -> int:
    try:
        handle: int = lg.gpiochip_open(chip)
    except Exception as exc:
        raise DriverError(
            f"cannot open /dev/gpiochip{chip} ({exc}); check that it exists (`ls /dev/gpiochip*`) and "
            "that the user is in the group that owns it (`sudo usermod -aG gpio $USER`, then log in again)"
        ) from exc
    return handle


def acquire(chip: int) -> tuple[Any, int]:
    """The lgpio module and a shared handle on `chip`; raises `DriverError` saying what to fix."""
    lg = lgpio_module()
    with _lock:
        entry = _shared.get(chip)
        if entry is not None:
            _shared[chip] = (entry[0], entry[1] + 1)
            return lg, entry[0]
        handle = _open(lg, chip)
        _shared[chip] = (handle, 1)
    log.info("opened gpiochip", chip=chip)
    return lg, handle


def release(lg: Any, chip: int, handle: int) -> None:
    """Give back a handle from `acquire`; its last user closes the chip."""
    with _lock:
        entry = _shared.get(chip)
        if entry is None or entry[0] != handle:
            return
        if entry[1] > 1:
            _shared[chip] = (handle, entry[1] - 1)
            return
        del _shared[chip]
    try:
        lg.gpiochip_close(handle)
    except Exception as exc:  # the chip is released by the kernel when the process ends anyway
        log.warning("gpiochip close failed", chip=chip, error=str(exc))


class LgpioHandle:
    """A driver's use of a gpiochip: `call("gpio_write", pin, 1)` passes the handle first; lgpio
    errors become `DriverError` naming the component. `close()` frees the lines it claimed.

    Pass `lg` to use a given module (tests hand in a `FakeLgpio`; the handle is then private);
    otherwise the process's shared handle on `chip` is acquired here and released by `close()`.
    """

    def __init__(self, component: str, chip: int, lg: Any = None) -> None:
        self.component = component
        self.chip = chip
        self._shared = lg is None
        if lg is None:
            self.lg, self.handle = acquire(chip)
        else:
            self.lg, self.handle = lg, _open(lg, chip)
        self.claimed: set[int] = set()
        self.closed = False

    def call(self, function: str, *args: Any) -> Any:
        """`lgpio.<function>(handle, *args)`; lgpio errors raise `DriverError`."""
        try:
            result = getattr(self.lg, function)(self.handle, *args)
        except Exception as exc:
            raise DriverError(f"{self.component}: lgpio {function}{args} failed: {exc}") from exc
        if function.startswith("gpio_claim_") and args:
            self.claimed.add(args[0])
        return result

    def close(self) -> None:
        """Free the claimed lines and release the chip; idempotent."""
        if self.closed:
            return
        self.closed = True
        for gpio in sorted(self.claimed):
            try:
                self.lg.gpio_free(self.handle, gpio)
            except Exception as exc:
                log.warning("gpio free failed", component=self.component, gpio=gpio, error=str(exc))
        if self._shared:
            release(self.lg, self.chip, self.handle)
        else:
            try:
                self.lg.gpiochip_close(self.handle)
            except Exception as exc:
                log.warning("gpiochip close failed", component=self.component, error=str(exc))
