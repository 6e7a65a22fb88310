"""The studio's web server (aiohttp): one page, its static assets and one WebSocket.

The socket carries the model and the robot's traffic from the server to the page. With a
`Workspace` (a model folder) the page also edits the model through `/api/*` requests (see
`umlbot.studio.api`); the server is the only writer of files, and only on a loopback bind. The
socket and every write check `Origin` (a page of another site in the same browser may neither read
nor write) and, on a loopback bind, `Host` (no DNS rebinding), whatever `--allow-remote` says; a
write also needs the per-run token the socket's hello carries. A refusal or a bad request is
answered with a JSON `{"error": …}` (`_json_errors`), never a traceback. docs/studio.md describes
the frames and requests; `umlbot/studio/web/` holds the page's sources.
"""

from __future__ import annotations

import asyncio
import contextlib
import errno
import gc
import ipaddress
import socket
import threading
from collections.abc import Callable
from dataclasses import dataclass, field
from importlib import resources
from pathlib import Path
from typing import Any, Protocol
from urllib.parse import urlsplit

from aiohttp import WSMsgType, web

from umlbot.base.errors import ConfigError
from umlbot.base.logs import get_logger
from umlbot.studio.data import MAX_BODY, StudioData
from umlbot.studio.hub import CLOSE_TOO_SLOW, MAX_PAGE_CHARS, Hub, Page, dumps, json_response
from umlbot.studio.layouts import LayoutCache

log = get_logger(__name__)

DEFAULT_HOST = "127.0.0.1"
DEFAULT_PORT = 8080
#: seconds between two checks for calls that stayed unanswered.
EXPIRE_EVERY_S = 1.0
#: seconds a dropped page has to take its close frame before its connection is aborted.
CLOSE_WAIT_S = 2.0


def static_dir() -> Path:
    """The built page (index.html, the bundle, its licences) inside the installed package."""
    return Path(str(resources.files("umlbot.studio") / "static"))


def is_loopback(host: str) -> bool:
    """True for 127.0.0.0/8, ::1 and localhost."""
    if host == "localhost":
        return True
    try:
        return ipaddress.ip_address(host.strip("[]")).is_loopback
    except ValueError:
        return False


def check_bind(host: str, allow_remote: bool) -> None:
    """Refuse a host name that does not resolve (that is the first thing to fix), then a
    non-loopback bind unless the user asked for it explicitly."""
    if is_loopback(host):
        return
    try:
        socket.getaddrinfo(host, None, type=socket.SOCK_STREAM)
    except (socket.gaierror, UnicodeError) as exc:
        reason = exc.strerror if isinstance(exc, socket.gaierror) and exc.strerror else str(exc)
        raise ConfigError(f"studio cannot listen on --host {host}: the name is not known "
                          f"({reason})") from None
    if not allow_remote:
        raise ConfigError(
            f"--host {host} would let anyone who can reach this machine watch the robot and its "
            "model; add --allow-remote to bind to it anyway (see docs/studio.md, Security)"
        )


def bind_error(host: str, port: int, exc: OSError, port_option: str = "--port") -> str:
    """The one line for a listener that could not start; the hint fits the cause and names the
    command's option that chooses the port (`port_option`)."""
    if isinstance(exc, socket.gaierror):
        return f"studio cannot listen on --host {host}: the name is not known ({exc.strerror or exc})"
    text = f"studio cannot listen on {host}:{port}: {exc.strerror or exc}"
    if exc.errno == errno.EADDRINUSE:
        return f"{text} (another studio? choose another port with {port_option})"
    if exc.errno == errno.EADDRNOTAVAIL:
        return f"{text} (--host must be an address of this machine)"
    return text


class EditRoutes(Protocol):
    """The editing requests a studio that edits a model folder serves (`umlbot.studio.api.EditApi`)."""

    def routes(self, app: web.Application, server: StudioServer) -> None:
        """Add the `/api/*` routes to `app`."""

    async def watch(self) -> None:
        """Watch the folder for changes on disk until cancelled."""

    def tick(self) -> None:
        """Called about once a second on the event loop."""

    def close(self) -> None:
        """Release what the editing session holds (called in an executor)."""


@dataclass
class StudioServer:
    """Serves `data` and the events of `hub` on `host:port` until `stop()`."""

    data: StudioData
    hub: Hub = field(default_factory=Hub)
    host: str = DEFAULT_HOST
    port: int = DEFAULT_PORT
    allow_remote: bool = False
    #: called about once a second on the event loop (expire unanswered calls, poll a world, …).
    tick: Callable[[], None] | None = None
    #: the editing requests (`/api/*`), when the studio edits a model folder.
    api: EditRoutes | None = None
    #: more routes: each is called with the app and this server (the fleet view's `/api/fleet`).
    extra_routes: list[Callable[[web.Application, StudioServer], None]] = field(default_factory=list)
    #: the command's option that sets `port` (named when the port is taken).
    port_option: str = "--port"
    #: characters of JSON one page may have waiting before it is dropped (`Page`).
    page_limit: int = MAX_PAGE_CHARS
    #: seconds between pings to each page; a page that does not answer one is closed.
    heartbeat_s: float = 20.0
    #: the layouts the page computed, kept (`/api/layout`, `umlbot.studio.layouts`); the command
    #: sets the model's own (with its shipped file), else the user's cache only.
    layouts: LayoutCache = field(default_factory=lambda: LayoutCache.for_model(None))
    _runner: web.AppRunner | None = None
    _tasks: list[asyncio.Task[None]] = field(default_factory=list)

    # --- life cycle ------------------------------------------------------------------------------

    def app(self) -> web.Application:
        app = web.Application(middlewares=[_json_errors], client_max_size=MAX_BODY)
        app.router.add_get("/", self._index)
        app.router.add_get("/ws", self._socket)
        app.router.add_static("/static/", static_dir(), follow_symlinks=False)
        self.layouts.routes(app, self)
        if self.api is not None:
            self.api.routes(app, self)
        for add_routes in self.extra_routes:
            add_routes(app, self)
        return app

    async def start(self) -> str:
        """Bind and serve; returns the page's URL. Raises ConfigError when the port is taken."""
        check_bind(self.host, self.allow_remote)
        if self.api is not None and not is_loopback(self.host):
            raise ConfigError(f"the studio edits a model only on a loopback --host, not {self.host} "
                              "(see docs/studio.md, Security)")
        self._runner = web.AppRunner(self.app(), access_log=None, handle_signals=False)
        await self._runner.setup()
        site = web.TCPSite(self._runner, self.host, self.port, reuse_address=True)
        try:
            await site.start()
        except OSError as exc:
            await self._runner.cleanup()
            raise ConfigError(bind_error(self.host, self.port, exc, self.port_option)) from exc
        server = getattr(site, "_server", None)
        sockets = getattr(server, "sockets", None) or []
        if sockets:
            self.port = int(sockets[0].getsockname()[1])
        self._tasks = [asyncio.create_task(self.hub.run(), name="studio-flush"),
                       asyncio.create_task(self._ticker(), name="studio-tick")]
        if self.api is not None:
            self._tasks.append(asyncio.create_task(self.api.watch(), name="studio-watch"))
        # What is loaded by now (modules, the catalog, the model as opened and checked) stays for
        # good: left out of the cyclic collector's full passes, which otherwise walk it all every
        # few edits (a pass of ~60 ms of an edit's answer on the 2 000-node model, docs/performance.md)
        gc.collect()
        gc.freeze()
        return self.url

    @property
    def url(self) -> str:
        host = f"[{self.host}]" if ":" in self.host else self.host
        return f"http://{host}:{self.port}/"

    async def stop(self) -> None:
        """Close every page and the listener; safe to call twice."""
        if self.api is not None:
            await asyncio.get_running_loop().run_in_executor(None, self.api.close)
        for task in self._tasks:
            task.cancel()
        for task in self._tasks:
            with contextlib.suppress(asyncio.CancelledError, Exception):
                await task
        self._tasks = []
        for page in list(self.hub.pages):
            self.hub.detach(page)
        if self._runner is not None:
            runner, self._runner = self._runner, None
            await runner.cleanup()

    async def _ticker(self) -> None:
        while True:
            await asyncio.sleep(EXPIRE_EVERY_S)
            for tick in (self.tick, self.api.tick if self.api is not None else None):
                if tick is None:
                    continue
                try:
                    tick()
                except Exception as exc:
                    log.warning("studio tick failed", error=str(exc))

    # --- handlers --------------------------------------------------------------------------------

    async def _index(self, request: web.Request) -> web.StreamResponse:
        self._check_host(request)
        index = static_dir() / "index.html"
        if not index.is_file():
            return web.Response(status=500, text="umlbot studio: the page's assets are missing from this "
                                "installation (umlbot/studio/static); reinstall umlbot")
        return web.FileResponse(index, headers={"Cache-Control": "no-store"})

    async def _socket(self, request: web.Request) -> web.StreamResponse:
        """One page's socket: every frame goes through its `Page` (the hello, the snapshot, the
        live frames), so what waits for a page that does not read is bounded; a page dropped for
        falling behind is closed with `CLOSE_TOO_SLOW` and the reason, and its connection is
        aborted (nothing it did not read is kept)."""
        self.check_origin(request)
        ws = web.WebSocketResponse(heartbeat=self.heartbeat_s, max_msg_size=1 << 16)
        await ws.prepare(request)
        transport = request.transport
        page = Page(ws.send_str, self.page_limit)
        page.greet(dumps(self.data.hello()))
        self.hub.attach(page)
        pump = asyncio.create_task(page.pump(), name="studio-page")
        reader = asyncio.create_task(self._read(ws), name="studio-page-reader")
        gone = asyncio.create_task(page.gone.wait(), name="studio-page-gone")
        try:
            await asyncio.wait({pump, reader, gone}, return_when=asyncio.FIRST_COMPLETED)
        finally:
            self.hub.detach(page)
            for task in (pump, gone):  # a pump stuck in a send to a page that does not read, too
                task.cancel()
                with contextlib.suppress(asyncio.CancelledError, Exception):
                    await task
            if page.dropped is not None:
                with contextlib.suppress(asyncio.TimeoutError, asyncio.CancelledError, Exception):
                    await asyncio.wait_for(ws.close(code=CLOSE_TOO_SLOW, message=page.dropped.encode()[:120]),
                                           CLOSE_WAIT_S)
            reader.cancel()
            with contextlib.suppress(asyncio.CancelledError, Exception):
                await reader
            if transport is not None and (page.dropped is not None or transport.get_write_buffer_size()):
                transport.abort()  # a peer that does not read would keep the buffer for ever
        return ws

    @staticmethod
    async def _read(ws: web.WebSocketResponse) -> None:
        """Read the page's socket to see it close (the page sends nothing)."""
        async for message in ws:
            if message.type == WSMsgType.ERROR:
                break

    def keeps_layouts(self) -> bool:
        """Whether a page may add to the layout cache: only on a loopback bind (a studio others can
        reach serves the layouts kept, it takes none from them)."""
        return is_loopback(self.host)

    def check_origin(self, request: web.Request) -> None:
        """Refuse a request from a page of another origin (and, on loopback, a foreign Host)."""
        self._check_host(request)
        origin = request.headers.get("Origin")
        if origin is not None and _netloc(origin) != request.host:
            log.warning("studio request refused: foreign origin", origin=origin[:200], path=request.path)
            raise web.HTTPForbidden(text=f"foreign origin {origin[:200]}: only the studio's own page "
                                         "may use it")

    def _check_host(self, request: web.Request) -> None:
        """On a loopback bind — the only one where the page can write — the Host must name this
        machine's loopback (`localhost`, 127.0.0.0/8, `::1`) or be the `--host` given, whatever
        `--allow-remote` says: a DNS-rebinding page (`evil.example` resolved to 127.0.0.1) is
        refused. The port is not compared: an SSH tunnel may forward another one, and a rebinding
        page chooses the name, not the port. A non-loopback bind is read-only and reached by names
        the studio cannot know: no check there (docs/security.md says so)."""
        if not (is_loopback(self.host) or self.api is not None):
            return
        try:
            host = urlsplit(f"//{request.host}").hostname or ""
        except ValueError:
            host = ""
        if not (is_loopback(host) or host == self.host.strip("[]").lower()):
            log.warning("studio request refused: foreign Host", host=request.host[:200], path=request.path)
            raise web.HTTPForbidden(text=f"host {request.host[:200]} is not this studio (open it as "
                                         "http://127.0.0.1 or http://localhost)")


def _netloc(url: str) -> str | None:
    """The `host:port` of a URL (None when it is not one: a malformed `[` IPv6 address)."""
    try:
        return urlsplit(url).netloc
    except ValueError:
        return None


@web.middleware
async def _json_errors(request: web.Request, handler: Any) -> web.StreamResponse:
    """Every refusal and bad request is answered with `{"error": "…"}` in words (what the page
    shows), and anything unforeseen with a 500 that says so in one line: the client never gets a
    traceback; the log gets the error (with its traceback only for an unforeseen one, a bug)."""
    try:
        response: web.StreamResponse = await handler(request)
        return response
    except web.HTTPException as exc:
        if exc.status < 400:
            raise
        text = exc.text or exc.reason
        if text.startswith(f"{exc.status}: "):  # aiohttp's own, e.g. "404: Not Found"
            text = text.removeprefix(f"{exc.status}: ")
        return json_response({"error": text, "message": text}, status=exc.status)
    except (asyncio.CancelledError, ConnectionResetError):
        raise
    except Exception as exc:
        log.exception("studio request failed", path=request.path[:200], error=str(exc)[:500])
        text = f"the studio failed on this request ({type(exc).__name__}); see its log"
        return json_response({"error": text, "message": text}, status=500)


class StudioThread:
    """A `StudioServer` on its own event loop thread (for `umlbot sim --studio`)."""

    def __init__(self, server: StudioServer) -> None:
        self.server = server
        self._loop = asyncio.new_event_loop()
        self._thread = threading.Thread(target=self._loop.run_forever, name="studio", daemon=True)
        self.url = ""

    def start(self, timeout: float = 10.0) -> str:
        self._thread.start()
        future = asyncio.run_coroutine_threadsafe(self.server.start(), self._loop)
        self.url = future.result(timeout)
        return self.url

    def stop(self, timeout: float = 5.0) -> None:
        if not self._thread.is_alive():
            return
        with contextlib.suppress(Exception):
            asyncio.run_coroutine_threadsafe(self.server.stop(), self._loop).result(timeout)
        self._loop.call_soon_threadsafe(self._loop.stop)
        self._thread.join(timeout)
