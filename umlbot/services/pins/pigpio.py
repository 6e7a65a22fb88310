"""One shared connection to the pigpio daemon per process, or the fake `pigpio.pi` for tests.

Only the pigpio drivers use this module, and only here is `pigpio` imported (lazily), so the rest
of umlbot runs on machines without it. All drivers of a process share one `pigpio.pi` per
(host, port), reference-counted: the last `release` calls `pi.stop()`.

The fake: `install_fake(FakePi())` makes every later `acquire` return that fake (tests in the same
process). For a service in another process set `UMLBOT_FAKE_PIGPIO=1` (a fresh `FakePi` is made
on first use) and optionally `UMLBOT_FAKE_PIGPIO_STATE=/path/state.json` (the fake rewrites its pin
state there after every output change, so a test can check that a killed service left its pins
at zero duty).
"""

from __future__ import annotations

import importlib
import os
import threading
from typing import TYPE_CHECKING, Any

from umlbot.base.errors import DriverError
from umlbot.base.logs import get_logger

if TYPE_CHECKING:  # the fake is imported only when the environment asks for it (below)
    from umlbot.testing.pigpio import FakePi

log = get_logger("umlbot.pigpio")

FAKE_ENV = "UMLBOT_FAKE_PIGPIO"
FAKE_STATE_ENV = "UMLBOT_FAKE_PIGPIO_STATE"

_lock = threading.Lock()
_fake: FakePi | None = None
_env_fake_users = 0  # users of a fake made from UMLBOT_FAKE_PIGPIO; the last one stops it
_env_fake: FakePi | None = None
_shared: dict[tuple[str, int], tuple[Any, int]] = {}


def install_fake(fake: FakePi | None) -> None:
    """Make `acquire` hand out `fake` (None: back to the real daemon or the env-selected fake)."""
    global _fake, _env_fake, _env_fake_users
    with _lock:
        _fake = fake
        _env_fake, _env_fake_users = None, 0


def installed_fake() -> FakePi | None:
    """The fake in use in this process, if any."""
    with _lock:
        return _fake


def _address(host: str | None, port: int | None) -> tuple[str, int]:
    # pigpio's own defaults: env PIGPIO_ADDR / PIGPIO_PORT, else localhost:8888.
    return (host or os.environ.get("PIGPIO_ADDR") or "localhost",
            int(port or os.environ.get("PIGPIO_PORT") or 8888))


def _env_wants_fake() -> bool:
    return os.environ.get(FAKE_ENV, "").strip().lower() in ("1", "true", "yes", "on")


def acquire(host: str | None = None, port: int | None = None) -> Any:
    """A connected `pigpio.pi` (or the fake); raises `DriverError` saying how to start pigpiod."""
    global _fake, _env_fake, _env_fake_users
    with _lock:
        if _fake is None and _env_wants_fake():
            from umlbot.testing.pigpio import FakePi  # tests only: a robot never loads the fake

            _fake = _env_fake = FakePi(state_file=os.environ.get(FAKE_STATE_ENV) or None)
            log.warning("using the fake pigpio (no hardware)", env=FAKE_ENV)
        if _fake is not None:
            if not _fake.connected:
                raise DriverError("cannot reach the pigpio daemon (fake disconnected)")
            if _fake is _env_fake:
                _env_fake_users += 1
            return _fake
        address = _address(host, port)
        entry = _shared.get(address)
        if entry is not None:
            _shared[address] = (entry[0], entry[1] + 1)
            return entry[0]
        try:
            pigpio = importlib.import_module("pigpio")
        except ImportError as exc:
            raise DriverError(
                "the pigpio Python package is not installed; install it with "
                "`pip install 'umlbot[pi]'` (or use --driver mock / sim)"
            ) from exc
        pi = pigpio.pi(address[0], address[1], show_errors=False)
        if not pi.connected:
            raise DriverError(
                f"cannot reach the pigpio daemon at {address[0]}:{address[1]}; start it with "
                "`sudo pigpiod` (or `sudo systemctl enable --now pigpiod`), or set PIGPIO_ADDR/PIGPIO_PORT"
            )
        _shared[address] = (pi, 1)
        log.info("connected to pigpiod", host=address[0], port=address[1])
        return pi


def release(pi: Any) -> None:
    """Give back a connection from `acquire`; its last user stops it (an installed fake: never)."""
    global _fake, _env_fake, _env_fake_users
    with _lock:
        if pi is _env_fake:
            _env_fake_users -= 1
            if _env_fake_users > 0:
                return
            if _fake is _env_fake:
                _fake = None
            _env_fake = None
        elif pi is _fake:
            return  # an installed fake lives as long as the test that installed it
        else:
            for address, (shared, count) in list(_shared.items()):
                if shared is pi:
                    if count > 1:
                        _shared[address] = (shared, count - 1)
                        return
                    del _shared[address]
                    break
            else:
                return  # not handed out here
    try:
        pi.stop()
    except Exception as exc:  # the daemon may already be gone; the connection is released anyway
        log.warning("pigpio stop failed", error=str(exc))


class PigpioHandle:
    """A driver's use of a `pigpio.pi`: calls that fail become `DriverError` naming the component.

    Pass `pi` to use a given connection (tests hand in a `FakePi`); otherwise the shared one is
    acquired here and released by `close()`.
    """

    def __init__(self, component: str, host: str | None = None, port: int | None = None,
                 pi: Any = None) -> None:
        self.component = component
        self._owned = pi is None
        self.pi: Any = acquire(host, port) if pi is None else pi
        self.closed = False

    def call(self, method: str, *args: Any) -> Any:
        """`pi.<method>(*args)`; pigpio errors and lost connections raise `DriverError`."""
        try:
            return getattr(self.pi, method)(*args)
        except Exception as exc:
            raise DriverError(f"{self.component}: pigpio {method}{args} failed: {exc}") from exc

    def close(self) -> None:
        """Release the connection if this handle acquired it; idempotent."""
        if self.closed:
            return
        self.closed = True
        if self._owned:
            release(self.pi)
