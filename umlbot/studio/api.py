"""The studio's editing requests: `/api/library`, `/api/files`, `/api/edit`, undo/redo, save, …

Every write (a POST) needs the per-run token the socket's hello carries and passes the server's
Origin and Host checks; the work (text edits, the compiler's check, file writes) runs in a worker
thread, one request at a time, so the page's live view never waits for it. docs/studio.md,
"Editing", is the reference of the requests and their answers.
"""

from __future__ import annotations

import asyncio
import contextlib
import secrets
from collections.abc import Awaitable, Callable
from typing import TYPE_CHECKING, Any

from aiohttp import web

from umlbot.base.files import loads_json
from umlbot.base.logs import get_logger
from umlbot.sim import bundled_tracks
from umlbot.studio.data import MAX_BODY
from umlbot.studio.hub import json_response
from umlbot.studio.run import RUN_SPEED, StudioRun, resolve_track
from umlbot.studio.textedit import EditError
from umlbot.studio.workspace import Conflict, SaveFailed, Workspace

if TYPE_CHECKING:
    from umlbot.studio.server import StudioServer

log = get_logger(__name__)

#: seconds between two looks at the model's files on disk.
WATCH_EVERY_S = 0.5

Handler = Callable[[dict[str, Any]], Any]


class EditApi:
    """The editing requests of one studio, over one `Workspace`."""

    def __init__(self, workspace: Workspace) -> None:
        self.workspace = workspace
        self.server: StudioServer | None = None
        self._lock = asyncio.Lock()
        self._loop: asyncio.AbstractEventLoop | None = None
        self.run: StudioRun | None = None
        self._warming: asyncio.Future[dict[str, Any]] | None = None  # the library's answer, made at start-up
        #: called with the model's name when the model on disk gets another one (the robot id
        #: follows it when neither --robot nor $UMLBOT_ROBOT chose one); on a worker thread.
        self.on_name: Callable[[str], None] | None = None
        #: called with one plain line when a Run ends (the terminal's account of it); on a worker thread.
        self.on_run_end: Callable[[str], None] | None = None

    def routes(self, app: web.Application, server: StudioServer) -> None:
        self.server = server
        self.run = StudioRun(server.hub, self.broadcast, say=lambda line: self._say_run(line))
        app.router.add_get("/api/library", self._library)
        app.on_startup.append(self._warm)
        app.router.add_get("/api/files", self._files)
        app.router.add_get("/api/tracks", self._tracks)
        posts: dict[str, Handler] = {
            "edit": lambda body: self.workspace.edit(body.get("version"), body.get("ops")),
            "undo": lambda body: self.workspace.undo(),
            "redo": lambda body: self.workspace.redo(),
            "save": lambda body: self._on_disk(self.workspace.save(body.get("version"),
                                                                    bool(body.get("force")))),
            "reload": lambda body: self._on_disk(self.workspace.reload()),
            "new": lambda body: self._on_disk(self.workspace.new_model(body.get("name"))),
            "recover": lambda body: self.workspace.recover(body.get("action")),
            "complete": self._complete,
            "run": self._run,
            "stop": lambda body: self._sim().stop(),
        }
        for name, handler in posts.items():
            app.router.add_post(f"/api/{name}", self._post(handler))

    # --- reading ---------------------------------------------------------------------------------

    async def _library(self, request: web.Request) -> web.StreamResponse:
        self._guard(request)
        # made once (every implementation's settings schema: ~0.5 s here, seconds on a busy
        # machine) in a worker thread, started with the studio (`_warm`): on the event loop it
        # held up the page's other first requests, its layout lookup among them, for as long
        return json_response(await asyncio.get_running_loop().run_in_executor(None, _library))

    async def _warm(self, app: web.Application) -> None:
        self._warming = asyncio.get_running_loop().run_in_executor(None, _library)

    async def _files(self, request: web.Request) -> web.StreamResponse:
        self._guard(request)
        async with self._lock:
            ws = self.workspace
            return json_response({"files": ws.texts(), "version": ws.version, "dirty": ws.dirty})

    def hello(self) -> dict[str, Any]:
        """The `edit` part of the socket's hello: the session, the model, a run going on."""
        return {**self.workspace.hello(), "run": self.run.current if self.run is not None
                else {"running": False}}

    async def _tracks(self, request: web.Request) -> web.StreamResponse:
        self._guard(request)
        return json_response({"tracks": list(bundled_tracks())})

    def _complete(self, body: dict[str, Any]) -> dict[str, Any]:
        from umlbot.studio.completion import complete

        text = body.get("text")
        cursor = body.get("cursor")
        if not isinstance(text, str) or not (cursor is None or isinstance(cursor, int)):
            raise EditError("complete needs 'text' (a string) and 'cursor' (an index into it)")
        field = body.get("field")
        lane = body.get("lane")
        return complete(self.workspace.answer_cache.get("model"), lane if isinstance(lane, str) else None,
                        text, cursor, field if isinstance(field, str) else None)

    def _say_run(self, line: str) -> None:
        if self.on_run_end is not None:
            self.on_run_end(line)

    def _sim(self) -> StudioRun:
        assert self.run is not None
        return self.run

    def _run(self, body: dict[str, Any]) -> dict[str, Any]:
        ws = self.workspace
        if ws.result is None or ws.result.model is None:
            raise Conflict({"error": "the model has errors: fix them before running it",
                            "version": ws.version})
        speed = body.get("speed", RUN_SPEED)
        if isinstance(speed, bool) or not isinstance(speed, int | float) or not 0.1 <= speed <= 100:
            raise EditError("'speed' is sim seconds per wall second, 0.1 to 100")
        return self._sim().start(ws.readable_files(), resolve_track(body.get("track") or "s_bend", ws.root),
                                 float(speed))

    def _poll(self, _: dict[str, Any]) -> list[dict[str, Any]]:
        frames = self.workspace.poll()
        if frames:
            self._on_disk({})
        return frames

    def _on_disk(self, answer: dict[str, Any]) -> dict[str, Any]:
        """The files on disk are the working copy now: the hello's `model` and `diagnostics` (the
        model a robot would run) become theirs, for pages that open from now on."""
        ws = self.workspace
        if self.server is not None and not ws.dirty and ws.result is not None:
            from umlbot.studio.model_view import diagnostic_view, model_view

            data = self.server.data
            data.model = model_view(ws.result.model) if ws.result.model is not None else None
            data.diagnostics = [diagnostic_view(d) for d in ws.result.diagnostics]
            name = ws.result.model.name if ws.result.model is not None else None
            if self.on_name is not None and name and name != data.robot:
                try:
                    self.on_name(name)
                except Exception as exc:  # e.g. a name that is no robot id: keep the robot followed
                    log.warning("studio: cannot follow the model's new name", name=name, error=str(exc))
        return answer

    def broadcast(self, frame: dict[str, Any]) -> None:
        """Send a frame to every page (from any thread)."""
        loop = self._loop
        if loop is not None and self.server is not None:
            with contextlib.suppress(RuntimeError):  # the loop has closed
                loop.call_soon_threadsafe(self.server.hub.broadcast, frame)

    def tick(self) -> None:
        """About once a second (the server's tick): a run's broker connection and calls."""
        if self.run is not None:
            self.run.tick()

    def close(self) -> None:
        """End a run that is going on (the studio stops)."""
        if self.run is not None and self.run.running:
            self.run.stop()

    # --- writing ---------------------------------------------------------------------------------

    def _guard(self, request: web.Request) -> None:
        assert self.server is not None
        self.server.check_origin(request)

    def _post(self, handler: Handler) -> Callable[[web.Request], Awaitable[web.StreamResponse]]:
        async def handle(request: web.Request) -> web.StreamResponse:
            self._guard(request)
            body = await _body(request)
            token = body.get("token")
            if not isinstance(token, str) or not secrets.compare_digest(token, self.workspace.token):
                log.warning("studio write refused: bad token", path=request.path)
                return json_response({"error": "missing or wrong token (reload the page)"}, 403)
            loop = self._loop = asyncio.get_running_loop()
            async with self._lock:
                try:
                    answer = await loop.run_in_executor(None, self._locked, handler, body)
                except Conflict as exc:
                    return json_response(exc.body, 409)
                except SaveFailed as exc:
                    return json_response(exc.body, exc.status)
                except EditError as exc:
                    return json_response(exc.answer(), 400)
                except ValueError as exc:
                    return _refuse(400, str(exc))
            return json_response(answer)

        return handle

    def _locked(self, handler: Handler, body: dict[str, Any]) -> Any:
        with self.workspace.lock:
            return handler(body)

    # --- files on disk -----------------------------------------------------------------------------

    async def watch(self) -> None:
        """Look at the model's files every `WATCH_EVERY_S` and tell the pages what changed."""
        loop = self._loop = asyncio.get_running_loop()
        while True:
            await asyncio.sleep(WATCH_EVERY_S)
            try:
                async with self._lock:
                    frames = await loop.run_in_executor(None, self._locked, self._poll, {})
            except Exception as exc:
                log.warning("studio: looking at the model's files failed", error=str(exc))
                continue
            if self.server is not None:
                for frame in frames:
                    self.server.hub.broadcast(frame)


def _refuse(status: int, text: str) -> web.Response:
    return json_response({"error": text, "message": text}, status)


async def _body(request: web.Request) -> dict[str, Any]:
    """The request's body: a JSON object in UTF-8 (RFC 8259), at most `MAX_BODY` bytes; anything
    else is refused with a 4xx answer that says what is wrong (raised as an HTTP error)."""
    if request.content_length is not None and request.content_length > MAX_BODY:
        raise web.HTTPRequestEntityTooLarge(MAX_BODY, request.content_length,
                                            text=f"request too large (at most {MAX_BODY} bytes)")
    try:
        charset = request.charset
    except ValueError:  # a Content-Type header that does not parse
        charset = "?"
    if charset is not None and charset.lower().replace("-", "").replace("_", "") != "utf8":
        raise web.HTTPUnsupportedMediaType(
            text=f"the request body is JSON in UTF-8, not charset={charset[:40]}")
    data = await request.read()  # more than client_max_size (MAX_BODY): 413
    try:
        body = loads_json(data.decode("utf-8"), finite=True)
    except UnicodeDecodeError as exc:
        raise web.HTTPBadRequest(text=f"the request body is not UTF-8 (byte {exc.start})") from None
    except ValueError as exc:  # a syntax error, nested too deeply, an integer too long
        raise web.HTTPBadRequest(text=f"the request body is not JSON: {str(exc)[:200]}") from None
    if not isinstance(body, dict):
        raise web.HTTPBadRequest(text="the request body is a JSON object")
    return body


def _library() -> dict[str, Any]:
    from umlbot.studio.library_view import library

    return library()
