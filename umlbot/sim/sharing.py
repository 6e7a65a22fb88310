"""Serving the one simulated world to sim drivers in other processes (`umlbot sim --processes`,
or services you start yourself): the server side of the protocol `umlbot.services.simworld`
defines, whose `RemoteWorld` is the client.
"""

from __future__ import annotations

import base64
import contextlib
import hmac
import json
import secrets
import socketserver
import threading
from typing import Any

from umlbot.base.logs import get_logger
from umlbot.services.simworld import ENV_ADDRESS, ENV_KEY
from umlbot.sim.world import World

log = get_logger(__name__)


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
    if op == "render_stereo":
        width = int(_number(args, "width_px", required=True) or 0)
        height = int(_number(args, "height_px", required=True) or 0)
        images = world.render_stereo(width, height)
        return {**images._asdict(), "left": base64.b64encode(images.left).decode(),
                "right": base64.b64encode(images.right).decode()}
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


