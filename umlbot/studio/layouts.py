"""The studio's layout cache: the positions ELK computed in the page for a lane, kept so that
opening a diagram that has not changed does not run ELK again (as Node-RED keeps x/y in its flows
and draw.io in its file).

The page computes a key, the SHA-256 of exactly what it gives ELK (nodes in order with their sizes,
flows, guard labels with their sizes, the layout options) and of the layout format and ELK's
version; it asks `GET /api/layout/<key>` before it runs ELK and, after a layout ELK made, sends it
with `POST /api/layout`. A changed diagram (an edit, a rename that makes a node wider, another
font) gives another key: ELK runs as before. The cache never holds anything but ELK's output, and
the page draws from it exactly as from ELK's own answer.

Entries are looked up in the user's cache (`$XDG_CACHE_HOME/umlbot/layouts`, else
`~/.cache/umlbot/layouts`; one file per key, at most `MAX_ENTRIES`, the least recently used go
first), then in a model's shipped file (`layout-cache.json` beside its YAML, written by
`scripts/layout_cache.py`: the reference models ship one, so their first open from a fresh clone
does not run ELK either). A file that does not read or does not hold a layout is a miss with a log
line; a cache that cannot be written is no cache. `UMLBOT_LAYOUT_CACHE=off` turns the cache off,
`=user` ignores the shipped files (the refresh script's fresh layouts). docs/studio.md, "Layout
cache".
"""

from __future__ import annotations

import asyncio
import contextlib
import json
import math
import os
import re
import tempfile
import threading
from pathlib import Path
from typing import Any, Protocol

from aiohttp import web

from umlbot.base.files import loads_json
from umlbot.base.logs import get_logger
from umlbot.studio.data import MAX_BODY
from umlbot.studio.hub import dumps, json_response

log = get_logger(__name__)

#: the file a model folder ships its layouts in.
SHIPPED_NAME = "layout-cache.json"
#: the version of the entries' format (the page's key covers its own format and ELK's version).
FORMAT = 1
#: layouts kept in the user's cache.
MAX_ENTRIES = 512
#: at most this many nodes, flows and points per flow in one layout.
MAX_NODES = 10_000
MAX_EDGES = 20_000
MAX_POINTS = 1_000
#: a shipped file larger than this is not read.
MAX_SHIPPED_BYTES = 16 << 20
KEY = re.compile(r"[0-9a-f]{64}")


class Guard(Protocol):
    """What the requests need of the server (`StudioServer`)."""

    def check_origin(self, request: web.Request) -> None:
        """Refuse a request from another origin or Host."""

    def keeps_layouts(self) -> bool:
        """Whether pages may add layouts."""


class LayoutError(ValueError):
    """A layout that is not one (what is wrong, in words)."""


def user_dir() -> Path:
    """`$XDG_CACHE_HOME/umlbot/layouts`, else `~/.cache/umlbot/layouts`."""
    base = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(base) / "umlbot" / "layouts"


def _number(value: Any, where: str) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(value):
        raise LayoutError(f"{where} is not a finite number")
    return value


def _point(value: Any, where: str) -> dict[str, float]:
    if not isinstance(value, dict):
        raise LayoutError(f"{where} is not a point {{x, y}}")
    return {"x": _number(value.get("x"), f"{where}.x"), "y": _number(value.get("y"), f"{where}.y")}


def _list(value: Any, where: str, limit: int) -> list[Any]:
    if not isinstance(value, list):
        raise LayoutError(f"{where} is not a list")
    if len(value) > limit:
        raise LayoutError(f"{where} has {len(value)} items (at most {limit})")
    return value


def _id(value: Any, where: str) -> str:
    if not isinstance(value, str) or not value or len(value) > 1000:
        raise LayoutError(f"{where} is not an id")
    return value


def check_layout(layout: Any) -> dict[str, Any]:
    """The layout of one lane as ELK gave it, with only what the page draws from: its size, each
    node's place and each flow's sections and label box. LayoutError says what is wrong."""
    if not isinstance(layout, dict):
        raise LayoutError("the layout is not an object")
    children = []
    for i, c in enumerate(_list(layout.get("children"), "children", MAX_NODES)):
        if not isinstance(c, dict):
            raise LayoutError(f"children[{i}] is not a node")
        children.append({"id": _id(c.get("id"), f"children[{i}].id"),
                         "x": _number(c.get("x"), f"children[{i}].x"),
                         "y": _number(c.get("y"), f"children[{i}].y")})
    edges = []
    for i, e in enumerate(_list(layout.get("edges"), "edges", MAX_EDGES)):
        if not isinstance(e, dict):
            raise LayoutError(f"edges[{i}] is not a flow")
        sections = []
        for j, s in enumerate(_list(e.get("sections"), f"edges[{i}].sections", MAX_POINTS)):
            at = f"edges[{i}].sections[{j}]"
            if not isinstance(s, dict):
                raise LayoutError(f"{at} is not a section")
            section: dict[str, Any] = {"startPoint": _point(s.get("startPoint"), f"{at}.startPoint"),
                                       "endPoint": _point(s.get("endPoint"), f"{at}.endPoint")}
            if "bendPoints" in s:
                section["bendPoints"] = [_point(p, f"{at}.bendPoints[{k}]") for k, p in
                                         enumerate(_list(s["bendPoints"], f"{at}.bendPoints", MAX_POINTS))]
            sections.append(section)
        edge: dict[str, Any] = {"id": _id(e.get("id"), f"edges[{i}].id"), "sections": sections}
        if "labels" in e:
            labels = []
            for k, lb in enumerate(_list(e["labels"], f"edges[{i}].labels", 4)):
                at = f"edges[{i}].labels[{k}]"
                if not isinstance(lb, dict):
                    raise LayoutError(f"{at} is not a label box")
                labels.append({name: _number(lb.get(name), f"{at}.{name}")
                               for name in ("x", "y", "width", "height")})
            edge["labels"] = labels
        edges.append(edge)
    return {"width": _number(layout.get("width"), "width"), "height": _number(layout.get("height"), "height"),
            "children": children, "edges": edges}


class LayoutCache:
    """The layouts one studio serves and keeps: the user's cache `folder` (None: none written or
    read) and the `shipped` files (read-only)."""

    def __init__(self, folder: Path | None, shipped: list[Path] | None = None) -> None:
        self.folder = folder
        self.shipped = list(shipped or [])
        self._shipped: dict[str, dict[str, Any]] | None = None
        self._write_failed = False
        self._lock = threading.Lock()

    @classmethod
    def for_model(cls, model: Path | None) -> LayoutCache:
        """The cache for a studio of `model` (a folder: its shipped file too), as
        `UMLBOT_LAYOUT_CACHE` says (`off`, `user`, else both)."""
        mode = os.environ.get("UMLBOT_LAYOUT_CACHE", "").strip().lower()
        if mode == "off":
            return cls(None)
        shipped = [model / SHIPPED_NAME] if model is not None and model.is_dir() and mode != "user" else []
        return cls(user_dir(), shipped)

    # --- reading ---------------------------------------------------------------------------------

    def _load_shipped(self) -> dict[str, dict[str, Any]]:
        with self._lock:  # requests are served in threads: the second waits for the first's read
            if self._shipped is None:
                shipped: dict[str, dict[str, Any]] = {}
                for path in self.shipped:
                    shipped.update(read_shipped(path))
                self._shipped = shipped
            return self._shipped

    def get(self, key: str) -> dict[str, Any] | None:
        """The layout kept under `key`, or None."""
        if not KEY.fullmatch(key):
            return None
        if self.folder is not None:
            path = self.folder / f"{key}.json"
            try:
                text = path.read_text(encoding="utf-8")
            except FileNotFoundError:
                text = None
            except OSError as exc:
                log.warning("layout cache: an entry does not read; ignored", path=str(path), error=str(exc))
                text = None
            if text is not None:
                try:
                    entry = loads_json(text, finite=True)
                    if not isinstance(entry, dict) or entry.get("format") != FORMAT:
                        raise LayoutError(f"not a layout of format {FORMAT}")
                    layout = check_layout(entry.get("layout"))
                except ValueError as exc:
                    log.warning("layout cache: a bad entry is ignored", path=str(path), error=str(exc)[:200])
                else:
                    with contextlib.suppress(OSError):
                        os.utime(path)  # recently used: kept longest
                    return layout
        if self.folder is None and not self.shipped:
            return None
        return self._load_shipped().get(key)

    # --- writing ---------------------------------------------------------------------------------

    def put(self, key: str, layout: dict[str, Any]) -> bool:
        """Keep `layout` (checked) under `key` in the user's cache; False when it cannot be written
        (said once in the log: a read-only home is no cache, not an error)."""
        if self.folder is None or not KEY.fullmatch(key):
            return False
        text = dumps({"format": FORMAT, "layout": layout})
        try:
            self.folder.mkdir(parents=True, exist_ok=True)
            fd, tmp = tempfile.mkstemp(dir=self.folder, prefix=".tmp-", suffix=".json")
            try:
                with os.fdopen(fd, "w", encoding="utf-8") as out:
                    out.write(text)
                os.replace(tmp, self.folder / f"{key}.json")
            except BaseException:
                with contextlib.suppress(OSError):
                    os.unlink(tmp)
                raise
        except OSError as exc:
            if not self._write_failed:
                log.warning("layout cache: cannot write; layouts are not kept", folder=str(self.folder),
                            error=str(exc))
                self._write_failed = True
            return False
        self._evict()
        return True

    def _evict(self) -> None:
        assert self.folder is not None
        try:
            entries = [(p.stat().st_mtime, p) for p in self.folder.glob("*.json")]
        except OSError:
            return
        if len(entries) <= MAX_ENTRIES:
            return
        entries.sort()
        for _, path in entries[: len(entries) - MAX_ENTRIES]:
            with contextlib.suppress(OSError):
                path.unlink()

    # --- requests --------------------------------------------------------------------------------

    def routes(self, app: web.Application, server: Guard) -> None:
        async def get(request: web.Request) -> web.StreamResponse:
            server.check_origin(request)
            key = request.match_info["key"]
            if not KEY.fullmatch(key):
                raise web.HTTPBadRequest(text="a layout key is 64 lower-case hex digits (SHA-256)")
            # on the loop: a small file read (~0.1 ms; the shipped file's first read ~2 ms), not a
            # hop to the default executor, which the editing session's work also uses
            # a miss is an answer, not an error: `layout` null (a 404 would be logged in the
            # browser's console for every diagram drawn before the cache has it)
            return json_response({"key": key, "layout": self.get(key)})

        async def post(request: web.Request) -> web.StreamResponse:
            server.check_origin(request)
            if not server.keeps_layouts():
                raise web.HTTPForbidden(text="a studio others can reach does not keep layouts")
            if request.content_length is not None and request.content_length > MAX_BODY:
                raise web.HTTPRequestEntityTooLarge(MAX_BODY, request.content_length,
                                                    text=f"a layout is at most {MAX_BODY} bytes")
            data = await request.read()
            try:
                body = loads_json(data.decode("utf-8"), finite=True)
            except (UnicodeDecodeError, ValueError) as exc:
                raise web.HTTPBadRequest(text=f"the request body is not JSON in UTF-8: {str(exc)[:200]}") \
                    from None
            if not isinstance(body, dict):
                raise web.HTTPBadRequest(text="the request body is a JSON object {key, layout}")
            key = body.get("key")
            if not isinstance(key, str) or not KEY.fullmatch(key):
                raise web.HTTPBadRequest(text="key: 64 lower-case hex digits (SHA-256) expected")
            try:
                layout = check_layout(body.get("layout"))
            except LayoutError as exc:
                raise web.HTTPBadRequest(text=f"layout: {exc}") from None
            kept = await _in_thread(self.put, key, layout)
            return json_response({"kept": kept})

        app.router.add_get("/api/layout/{key}", get)
        app.router.add_post("/api/layout", post)


def read_shipped(path: Path) -> dict[str, dict[str, Any]]:
    """The layouts of a shipped file (key -> layout); a file that is missing is none, one that is
    bad is none with a log line, a bad entry in it is left out with a log line."""
    try:
        if path.stat().st_size > MAX_SHIPPED_BYTES:
            raise LayoutError(f"larger than {MAX_SHIPPED_BYTES} bytes")
        data = loads_json(path.read_text(encoding="utf-8"), finite=True)
        if not isinstance(data, dict) or data.get("format") != FORMAT \
                or not isinstance(data.get("layouts"), dict):
            raise LayoutError(f"not a layout cache of format {FORMAT}")
    except FileNotFoundError:
        return {}
    except (OSError, ValueError) as exc:
        log.warning("layout cache: a shipped file is ignored", path=str(path), error=str(exc)[:200])
        return {}
    layouts: dict[str, dict[str, Any]] = {}
    for key, layout in data["layouts"].items():
        try:
            if not KEY.fullmatch(key):
                raise LayoutError("the key is not a SHA-256")
            layouts[key] = check_layout(layout)
        except LayoutError as exc:
            log.warning("layout cache: a shipped entry is ignored", path=str(path), key=key[:80],
                        error=str(exc)[:200])
    return layouts


def write_shipped(path: Path, layouts: dict[str, dict[str, Any]]) -> None:
    """Write a shipped file (sorted, one entry a line, so that a refresh diffs by lane)."""
    lines = [f"  {json.dumps(key)}: {json.dumps(check_layout(layouts[key]), separators=(',', ':'))}"
             for key in sorted(layouts)]
    path.write_text(f'{{"format": {FORMAT}, "layouts": {{\n' + ",\n".join(lines) + "\n}}\n", encoding="utf-8")


async def _in_thread(fn: Any, *args: Any) -> Any:
    return await asyncio.get_running_loop().run_in_executor(None, fn, *args)

