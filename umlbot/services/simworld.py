"""The seam between the sim drivers and the simulated world: the services define it, the sim
implements it.

A sim driver (`umlbot/services/<kind>/sim.py`) reaches the one simulated world through a
`WorldHandle`, which `connect_world` gives it: the world attached to this process
(`attach_local_world`, what `umlbot sim` does without `--processes`), else a `RemoteWorld`
speaking to the world another process serves (`umlbot.sim.sharing.WorldServer`). That protocol is
JSON lines over TCP on 127.0.0.1, one request and one reply per line, opened by a
`{"op": "hello", "key": …}` line carrying a random key. The address and the key reach the
service processes in the environment::

    UMLBOT_SIM_WORLD=127.0.0.1:40123   UMLBOT_SIM_KEY=<hex>

The world travels as plain values (sides, percents, degrees, centimetres): no pickles, no MQTT;
the drivers know nothing of the bus, and nothing of the sim's internals.
"""

from __future__ import annotations

import base64
import contextlib
import json
import os
import socket
import threading
from typing import Any, Literal, NamedTuple, Protocol

from umlbot.base.errors import SimError

ENV_ADDRESS = "UMLBOT_SIM_WORLD"
ENV_KEY = "UMLBOT_SIM_KEY"

#: A side of the car: each motor channel drives one.
Side = Literal["left", "right"]


class StereoImages(NamedTuple):
    """One picture of the simulated stereo camera: two 8-bit grey images (row-major bytes) and
    the ideal rig that took them (focal length in pixels, baseline in metres)."""

    time_s: float
    width_px: int
    height_px: int
    focal_px: float
    baseline_m: float
    left: bytes
    right: bytes


class WorldHandle(Protocol):
    """What a sim driver may do to the world (a `World` or a `RemoteWorld`)."""

    def set_motor(
        self, side: Side, *, enabled: bool | None = None, forward: bool | None = None,
        duty_percent: float | None = None,
    ) -> None: ...

    def renew_motor(self, side: Side, lease_s: float) -> bool: ...

    def set_servo(self, degrees: float) -> None: ...

    def servo_angle_deg(self) -> float: ...

    def read_sonar_cm(self) -> int | None: ...

    def time_s(self) -> float: ...

    def render_stereo(self, width_px: int, height_px: int) -> StereoImages: ...


_local: WorldHandle | None = None
_local_lock = threading.Lock()


def attach_local_world(world: WorldHandle | None) -> None:
    """Make `world` the one the sim drivers of this process use (None detaches it)."""
    global _local
    with _local_lock:
        _local = world


def connect_world() -> WorldHandle:
    """The world for a sim driver: the attached local one, else the one named by the environment."""
    with _local_lock:
        if _local is not None:
            return _local
    address = os.environ.get(ENV_ADDRESS)
    if not address:
        raise SimError(
            f"no simulated world: run the service under 'umlbot sim', or set {ENV_ADDRESS}=host:port "
            f"and {ENV_KEY} to a world served by 'umlbot sim'"
        )
    return RemoteWorld(address, os.environ.get(ENV_KEY, ""))


# --- client ------------------------------------------------------------------------------------


class RemoteWorld:
    """A world served by `WorldServer` in another process; one connection, calls serialised."""

    def __init__(self, address: str, key: str, timeout_s: float = 2.0) -> None:
        host, _, port = address.rpartition(":")
        if not host or not port.isdigit():
            raise SimError(f"{ENV_ADDRESS} must be host:port, got {address!r}")
        self._address = (host, int(port))
        self._key = key
        self._timeout_s = timeout_s
        self._lock = threading.Lock()
        self._sock: socket.socket | None = None
        self._file: Any = None

    def _connect(self) -> None:
        try:
            sock = socket.create_connection(self._address, timeout=self._timeout_s)
        except OSError as exc:
            where = f"{self._address[0]}:{self._address[1]}"
            raise SimError(f"simulated world at {where} unreachable: {exc}") from exc
        sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
        self._sock, self._file = sock, sock.makefile("rwb")
        reply = self._exchange({"op": "hello", "key": self._key})
        if not reply.get("ok"):
            self.close()
            raise SimError(f"simulated world refused the connection: {reply.get('error')}")

    def _exchange(self, request: dict[str, Any]) -> dict[str, Any]:
        self._file.write(json.dumps(request).encode() + b"\n")
        self._file.flush()
        line = self._file.readline()
        if not line:
            raise OSError("world closed the connection")
        reply: dict[str, Any] = json.loads(line)
        return reply

    def _call(self, op: str, **args: Any) -> Any:
        with self._lock:
            for attempt in (1, 2):  # one reconnect: the world may have been restarted
                try:
                    if self._sock is None:
                        self._connect()
                    reply = self._exchange({"op": op, "args": args})
                    break
                except (OSError, ValueError) as exc:
                    self.close()
                    if attempt == 2:
                        raise SimError(f"simulated world call {op} failed: {exc}") from exc
            if not reply.get("ok"):
                raise ValueError(str(reply.get("error")))
            return reply.get("value")

    def set_motor(
        self, side: Side, *, enabled: bool | None = None, forward: bool | None = None,
        duty_percent: float | None = None,
    ) -> None:
        self._call("set_motor", side=side, enabled=enabled, forward=forward, duty_percent=duty_percent)

    def renew_motor(self, side: Side, lease_s: float) -> bool:
        return bool(self._call("renew_motor", side=side, lease_s=lease_s))

    def set_servo(self, degrees: float) -> None:
        self._call("set_servo", degrees=degrees)

    def servo_angle_deg(self) -> float:
        return float(self._call("servo_angle_deg"))

    def read_sonar_cm(self) -> int | None:
        value = self._call("read_sonar_cm")
        return None if value is None else int(value)

    def time_s(self) -> float:
        return float(self._call("time_s"))

    def render_stereo(self, width_px: int, height_px: int) -> StereoImages:
        value = self._call("render_stereo", width_px=width_px, height_px=height_px)
        try:
            return StereoImages(float(value["time_s"]), int(value["width_px"]), int(value["height_px"]),
                                float(value["focal_px"]), float(value["baseline_m"]),
                                base64.b64decode(value["left"]), base64.b64decode(value["right"]))
        except (KeyError, TypeError, ValueError) as exc:
            raise SimError(f"simulated world sent a bad stereo picture: {exc}") from exc

    def close(self) -> None:
        """Drop the connection; idempotent (the next call reconnects)."""
        for thing in (self._file, self._sock):
            if thing is not None:
                with contextlib.suppress(OSError):
                    thing.close()
        self._sock, self._file = None, None
