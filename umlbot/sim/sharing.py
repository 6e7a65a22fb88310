"""How the sim drivers reach the one simulated world, in the same process or from another one.

In-process (`umlbot sim` without `--processes`) the runner calls `attach_local_world(world)` and
the drivers use the `World` object directly. Across processes (`umlbot sim --processes`, or
services you start yourself) the runner also serves the world with `WorldServer`: a tiny protocol
of JSON lines over TCP on 127.0.0.1, one request and one reply per line, opened by a
`{"op": "hello", "key": …}` line carrying a random key. The address and the key reach the
service processes in the environment::

    UMLBOT_SIM_WORLD=127.0.0.1:40123   UMLBOT_SIM_KEY=<hex>

The world travels as plain values (sides, percents, degrees, centimetres): no pickles, no MQTT;
the drivers know nothing of the bus.
"""

from __future__ import annotations

import contextlib
import hmac
import json
import os
import secrets
import socket
import socketserver
import threading
from typing import Any, Protocol

from umlbot.base.errors import SimError
from umlbot.base.logs import get_logger
from umlbot.sim.world import Side, World

log = get_logger(__name__)

ENV_ADDRESS = "UMLBOT_SIM_WORLD"
ENV_KEY = "UMLBOT_SIM_KEY"


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


_local: World | None = None
_local_lock = threading.Lock()


def attach_local_world(world: World | None) -> None:
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


# --- server ------------------------------------------------------------------------------------


def _flag(args: dict[str, Any], name: str) -> bool | None:
    value = args.get(name)
    if value is not None and not isinstance(value, bool):
        raise ValueError(f"{name} must be true, false or null, got {type(value).__name__}")
    return value


def _number(args: dict[str, Any], name: str, required: bool = False) -> float | None:
    value = args.get(name)
    if value is None and not required:
        return None
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise ValueError(f"{name} must be a number, got {type(value).__name__}")
    try:
        number = float(value)
    except OverflowError:
        raise ValueError(f"{name} is too large") from None
    if number != number:  # NaN passes every range check
        raise ValueError(f"{name} must be a number, got NaN")
    return number


def _dispatch(world: World, op: str, args: dict[str, Any]) -> Any:
    """Run one request on the world; `ValueError` for a request it cannot take."""
    if op == "set_motor":
        side = args.get("side")
        if side not in ("left", "right"):
            raise ValueError(f"side must be 'left' or 'right', got {side!r}"[:80])
        world.set_motor(side, enabled=_flag(args, "enabled"), forward=_flag(args, "forward"),
                        duty_percent=_number(args, "duty_percent"))
        return None
    if op == "renew_motor":
        side = args.get("side")
        if side not in ("left", "right"):
            raise ValueError(f"side must be 'left' or 'right', got {side!r}"[:80])
        lease = _number(args, "lease_s", required=True)
        assert lease is not None
        return world.renew_motor(side, lease)
    if op == "set_servo":
        degrees = _number(args, "degrees", required=True)
        assert degrees is not None
        world.set_servo(degrees)
        return None
    if op == "servo_angle_deg":
        return world.servo_angle_deg()
    if op == "read_sonar_cm":
        return world.read_sonar_cm()
    if op == "time_s":
        return world.time_s()
    raise ValueError(f"unknown operation {op!r}"[:80])


#: the longest request line the world server reads (bytes, without its newline).
MAX_LINE = 65536


class _Handler(socketserver.StreamRequestHandler):
    """One sim driver's connection: a keyed hello, then one JSON request and one reply per line.

    A bad line (not JSON, nested too deeply, longer than 64 KiB, an unknown operation, a wrong
    argument) gets `{"ok": false, "error": ...}` and one warning in the log; the connection and
    the world keep going.
    """

    server: _TCPServer

    def handle(self) -> None:
        hello = self._read()
        if hello is None or hello.get("op") != "hello" or not hmac.compare_digest(
            str(hello.get("key", "")).encode(), self.server.key.encode()
        ):
            log.warning("sim_world_client_refused", reason="no hello with the key")
            self._write({"ok": False, "error": "bad key"})
            return
        self._write({"ok": True, "value": None})
        while (request := self._read()) is not None:
            args = request.get("args")
            try:
                if args is not None and not isinstance(args, dict):
                    raise ValueError("args must be a JSON object")
                value = _dispatch(self.server.world, str(request.get("op"))[:80], args or {})
                self._write({"ok": True, "value": value})
            except ValueError as exc:
                log.warning("sim_world_request_refused", op=str(request.get("op"))[:80], error=str(exc))
                self._write({"ok": False, "error": str(exc)})

    def _read(self) -> dict[str, Any] | None:
        line = self.rfile.readline(MAX_LINE + 1)
        if not line:
            return None
        if len(line) > MAX_LINE and not line.endswith(b"\n"):
            while (rest := self.rfile.readline(MAX_LINE)) and not rest.endswith(b"\n"):
                pass  # the rest of the over-long line: one reply per line, however long it is
            return {"op": f"invalid line (longer than {MAX_LINE // 1024} KiB)"}
        try:
            data = json.loads(line)
        except (ValueError, RecursionError):  # RecursionError: nested too deeply for the decoder
            return {"op": "invalid line (not JSON)"}
        return data if isinstance(data, dict) else {"op": "invalid line (not a JSON object)"}

    def _write(self, reply: dict[str, Any]) -> None:
        with contextlib.suppress(OSError):
            self.wfile.write(json.dumps(reply).encode() + b"\n")


class _TCPServer(socketserver.ThreadingTCPServer):
    daemon_threads = True
    allow_reuse_address = True

    def __init__(self, address: tuple[str, int], world: World, key: str) -> None:
        super().__init__(address, _Handler)
        self.world = world
        self.key = key


class WorldServer:
    """Serves one world to sim drivers in other processes; `env` is what those processes need."""

    def __init__(self, world: World, host: str = "127.0.0.1", port: int = 0, key: str | None = None) -> None:
        self.world = world
        self.key = key or secrets.token_hex(16)
        self._server = _TCPServer((host, port), world, self.key)
        self._thread: threading.Thread | None = None

    @property
    def address(self) -> str:
        host, port = self._server.server_address[:2]
        return f"{host!s}:{port}"

    @property
    def env(self) -> dict[str, str]:
        return {ENV_ADDRESS: self.address, ENV_KEY: self.key}

    def start(self) -> WorldServer:
        if self._thread is None:
            self._thread = threading.Thread(target=self._server.serve_forever, name="sim-world-server",
                                            kwargs={"poll_interval": 0.1}, daemon=True)
            self._thread.start()
            log.debug("world server listening", address=self.address)
        return self

    def stop(self) -> None:
        """Stop serving; idempotent."""
        if self._thread is not None:
            self._server.shutdown()
            self._thread.join(timeout=2.0)
            self._thread = None
        self._server.server_close()


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

    def close(self) -> None:
        """Drop the connection; idempotent (the next call reconnects)."""
        for thing in (self._file, self._sock):
            if thing is not None:
                with contextlib.suppress(OSError):
                    thing.close()
        self._sock, self._file = None, None
