"""systemd's service notifications (`sd_notify`) without a dependency: one datagram each.

A unit with `Type=notify` waits for `READY=1`; with `WatchdogSec=` systemd sets `WATCHDOG_USEC`
(and `WATCHDOG_PID`) and kills the service when no `WATCHDOG=1` came for that long. Outside
systemd (`NOTIFY_SOCKET` unset) every call does nothing, so the same code runs anywhere.
"""

from __future__ import annotations

import os
import socket

from umlbot.base.logs import get_logger

log = get_logger(__name__)


def notify(*states: str) -> bool:
    """Send `KEY=VALUE` lines to systemd; True when sent, False without a `NOTIFY_SOCKET`."""
    address = os.environ.get("NOTIFY_SOCKET")
    if not address or not states:
        return False
    if address.startswith("@"):  # an abstract socket
        address = "\0" + address[1:]
    try:
        with socket.socket(socket.AF_UNIX, socket.SOCK_DGRAM | socket.SOCK_CLOEXEC) as sock:
            sock.sendto("\n".join(states).encode("utf-8"), address)
    except OSError as exc:
        log.warning("sd_notify_failed", error=str(exc), states=list(states))
        return False
    return True


def watchdog_s() -> float | None:
    """The watchdog time-out systemd asked for (`WatchdogSec=`) in seconds, None without one (or
    when it was meant for another process: `WATCHDOG_PID`)."""
    usec = os.environ.get("WATCHDOG_USEC", "")
    pid = os.environ.get("WATCHDOG_PID", "")
    if not usec.isdigit() or int(usec) <= 0 or (pid and pid != str(os.getpid())):
        return None
    return int(usec) / 1_000_000
