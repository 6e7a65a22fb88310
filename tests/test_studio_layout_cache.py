"""The studio's layout cache on the server (umlbot/studio/layouts.py): `/api/layout` over a real
socket, what it refuses and why, its bounds, and that a bad file or a cache that cannot be written
is no cache rather than an error. The page's side: tests/test_studio_layout_cache_browser.py."""

from __future__ import annotations

import asyncio
import json
from collections.abc import AsyncGenerator
from pathlib import Path
from typing import Any

import aiohttp
import pytest

from umlbot.studio import layouts as layouts_module
from umlbot.studio.data import MAX_BODY, StudioData
from umlbot.studio.layouts import (
    SHIPPED_NAME,
    LayoutCache,
    LayoutError,
    check_layout,
    read_shipped,
    write_shipped,
)
from umlbot.studio.server import StudioServer

KEY = "ab" * 32
OTHER = "cd" * 32
LAYOUT: dict[str, Any] = {
    "width": 320, "height": 448.5,
    "children": [{"id": "start", "x": 140, "y": 21}, {"id": "go", "x": 24.25, "y": 76}],
    "edges": [{"id": "start->go", "sections": [{"startPoint": {"x": 151, "y": 43},
                                                "endPoint": {"x": 151, "y": 76},
                                                "bendPoints": [{"x": 151, "y": 60}]}],
               "labels": [{"x": 1, "y": 2, "width": 30, "height": 16}]}],
}


async def _serve(cache: LayoutCache) -> AsyncGenerator[tuple[StudioServer, str], None]:
    data = StudioData(mode="live", robot="car", source="x", model=None, diagnostics=[])
    server = StudioServer(data, port=0, layouts=cache)
    url = await server.start()
    try:
        yield server, url.rstrip("/")
    finally:
        await server.stop()


class Said:
    """The layout cache's log, recorded (whatever an earlier test configured logging to)."""

    def __init__(self) -> None:
        self.lines: list[str] = []

    def warning(self, event: str, **fields: Any) -> None:
        self.lines.append(event)

    def text(self) -> str:
        return "\n".join(self.lines)


@pytest.fixture
def said(monkeypatch: pytest.MonkeyPatch) -> Said:
    recorder = Said()
    monkeypatch.setattr(layouts_module, "log", recorder)
    return recorder


def run(cache: LayoutCache, steps: Any) -> Any:
    async def main() -> Any:
        gen = _serve(cache)
        _, url = await gen.__anext__()
        try:
            async with aiohttp.ClientSession() as client:
                return await steps(client, url)
        finally:
            await gen.aclose()

    return asyncio.run(main())


async def _post(client: aiohttp.ClientSession, url: str, body: Any,
                origin: str | None = None) -> tuple[int, Any]:
    data = body if isinstance(body, bytes) else json.dumps(body).encode()
    headers = {"Content-Type": "application/json", **({"Origin": origin} if origin else {})}
    async with client.post(f"{url}/api/layout", data=data, headers=headers) as res:
        return res.status, await res.json()


async def _get(client: aiohttp.ClientSession, url: str, key: str) -> tuple[int, Any]:
    async with client.get(f"{url}/api/layout/{key}") as res:
        return res.status, await res.json()


def test_a_layout_the_page_sends_is_served_back_under_its_key(tmp_path: Path) -> None:
    cache = LayoutCache(tmp_path / "layouts")

    async def steps(client: aiohttp.ClientSession, url: str) -> None:
        assert await _get(client, url, KEY) == (200, {"key": KEY, "layout": None})  # none kept
        extra = {**LAYOUT, "id": "root",
                 "children": [{**c, "width": 9, "labels": []} for c in LAYOUT["children"]]}
        assert await _post(client, url, {"key": KEY, "layout": extra}) == (200, {"kept": True})
        status, body = await _get(client, url, KEY)
        assert status == 200
        assert body == {"key": KEY, "layout": LAYOUT}  # only what the page draws from is kept
        assert await _get(client, url, OTHER) == (200, {"key": OTHER, "layout": None})

    run(cache, steps)
    assert [p.name for p in (tmp_path / "layouts").iterdir()] == [f"{KEY}.json"]


@pytest.mark.parametrize(("body", "status", "says"), [
    ({"key": "AB" * 32, "layout": LAYOUT}, 400, "key: 64 lower-case hex digits"),
    ({"key": "../" + KEY[3:], "layout": LAYOUT}, 400, "key: 64 lower-case hex digits"),
    ({"layout": LAYOUT}, 400, "key: 64 lower-case hex digits"),
    ({"key": KEY}, 400, "layout: the layout is not an object"),
    ({"key": KEY, "layout": {**LAYOUT, "width": "wide"}}, 400, "layout: width is not a finite number"),
    ({"key": KEY, "layout": {**LAYOUT, "children": [{"id": "a", "x": 1, "y": True}]}}, 400,
     "layout: children[0].y is not a finite number"),
    ({"key": KEY, "layout": {**LAYOUT, "edges": [{"id": "e", "sections": [{"startPoint": {"x": 1}}]}]}}, 400,
     "layout: edges[0].sections[0].startPoint.y is not a finite number"),
    ({"key": KEY, "layout": {**LAYOUT, "children": [{"id": "a", "x": 0, "y": 0}] * 10_001}}, 400,
     "layout: children has 10001 items (at most 10000)"),
    ([KEY, LAYOUT], 400, "the request body is a JSON object {key, layout}"),
    (b'{"key": "' + KEY.encode() + b'", "layout": NaN}', 400, "not JSON"),
    (b"\xff\xfe", 400, "not JSON in UTF-8"),
])
def test_a_bad_layout_is_refused_with_what_is_wrong_and_nothing_is_written(
        tmp_path: Path, body: Any, status: int, says: str) -> None:
    cache = LayoutCache(tmp_path / "layouts")

    async def steps(client: aiohttp.ClientSession, url: str) -> tuple[int, Any]:
        return await _post(client, url, body)

    got, answer = run(cache, steps)
    assert got == status, answer
    assert says in answer["error"], answer
    assert not (tmp_path / "layouts").exists() or not list((tmp_path / "layouts").iterdir())


def test_the_size_of_a_layout_and_of_the_cache_is_bounded(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(layouts_module, "MAX_ENTRIES", 3)
    cache = LayoutCache(tmp_path / "layouts")
    big = {"key": KEY, "layout": {**LAYOUT, "pad": "x" * MAX_BODY}}

    async def steps(client: aiohttp.ClientSession, url: str) -> list[Any]:
        out = [await _post(client, url, big)]
        for i in range(5):
            out.append(await _post(client, url, {"key": f"{i:064x}", "layout": LAYOUT}))
        out.append(await _get(client, url, "../../etc/passwd"))
        out.append(await _get(client, url, "a" * 63))
        return out

    answers = run(cache, steps)
    assert answers[0][0] == 413 and str(MAX_BODY) in answers[0][1]["error"], answers[0]
    assert all(a == (200, {"kept": True}) for a in answers[1:6]), answers
    assert answers[6][0] == 404  # not a route
    assert answers[7] == (400, {"error": "a layout key is 64 lower-case hex digits (SHA-256)",
                                "message": "a layout key is 64 lower-case hex digits (SHA-256)"})
    assert len(list((tmp_path / "layouts").glob("*.json"))) == 3  # the least recently used went


def test_a_foreign_page_and_a_studio_others_reach_add_no_layouts(tmp_path: Path) -> None:
    cache = LayoutCache(tmp_path / "layouts")

    async def steps(client: aiohttp.ClientSession, url: str) -> tuple[int, Any]:
        return await _post(client, url, {"key": KEY, "layout": LAYOUT}, origin="http://evil.example")

    status, answer = run(cache, steps)
    assert status == 403 and "foreign origin" in answer["error"]
    assert not (tmp_path / "layouts").exists()
    data = StudioData(mode="live", robot="car", source="x", model=None, diagnostics=[])
    assert StudioServer(data).keeps_layouts()
    assert not StudioServer(data, host="192.0.2.7", allow_remote=True).keeps_layouts()


def test_a_bad_entry_or_shipped_file_is_a_miss_with_a_log_line(tmp_path: Path, said: Said) -> None:
    folder = tmp_path / "layouts"
    folder.mkdir()
    (folder / f"{KEY}.json").write_text("{not json", encoding="utf-8")
    (folder / f"{OTHER}.json").write_text(json.dumps({"format": 1, "layout": {"width": 1}}), encoding="utf-8")
    model = tmp_path / "model"
    model.mkdir()
    (model / SHIPPED_NAME).write_text("[]", encoding="utf-8")
    cache = LayoutCache(folder, [model / SHIPPED_NAME])

    async def steps(client: aiohttp.ClientSession, url: str) -> list[Any]:
        return [await _get(client, url, KEY), await _get(client, url, OTHER)]

    assert run(cache, steps) == [(200, {"key": KEY, "layout": None}), (200, {"key": OTHER, "layout": None})]
    err = said.text()
    assert "layout cache: a bad entry is ignored" in err and "layout cache: a shipped file is ignored" in err
    # a shipped file with one bad entry: the others are served
    write_shipped(model / SHIPPED_NAME, {KEY: LAYOUT})
    text = (model / SHIPPED_NAME).read_text(encoding="utf-8")
    assert text.endswith("\n}}\n")
    (model / SHIPPED_NAME).write_text(text[:-4] + f',\n  "{OTHER}": {{"width": 1}}\n}}}}\n', encoding="utf-8")
    assert read_shipped(model / SHIPPED_NAME) == {KEY: LAYOUT}
    assert "a shipped entry is ignored" in said.text()
    assert LayoutCache(tmp_path / "empty", [model / SHIPPED_NAME]).get(KEY) == LAYOUT


def test_a_cache_that_cannot_be_written_is_no_cache_not_an_error(tmp_path: Path, said: Said) -> None:
    blocker = tmp_path / "cache"
    blocker.write_text("a file where the cache folder would be", encoding="utf-8")
    cache = LayoutCache(blocker / "umlbot" / "layouts")

    async def steps(client: aiohttp.ClientSession, url: str) -> list[Any]:
        return [await _post(client, url, {"key": KEY, "layout": LAYOUT}),
                await _post(client, url, {"key": OTHER, "layout": LAYOUT}),
                await _get(client, url, KEY)]

    answers = run(cache, steps)
    assert answers[:2] == [(200, {"kept": False})] * 2
    assert answers[2] == (200, {"key": KEY, "layout": None})  # a miss
    assert said.text().count("layout cache: cannot write") == 1  # said once


def test_the_environment_chooses_the_caches(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "xdg"))
    monkeypatch.delenv("UMLBOT_LAYOUT_CACHE", raising=False)
    both = LayoutCache.for_model(tmp_path)
    assert both.folder == tmp_path / "xdg" / "umlbot" / "layouts"
    assert both.shipped == [tmp_path / SHIPPED_NAME]
    monkeypatch.setenv("UMLBOT_LAYOUT_CACHE", "user")
    assert LayoutCache.for_model(tmp_path).shipped == []
    monkeypatch.setenv("UMLBOT_LAYOUT_CACHE", "off")
    off = LayoutCache.for_model(tmp_path)
    assert off.folder is None and off.shipped == [] and not off.put(KEY, LAYOUT) and off.get(KEY) is None


def test_check_layout_keeps_only_the_drawn_fields_and_refuses_a_non_layout() -> None:
    assert check_layout({**LAYOUT, "id": "root", "layoutOptions": {"a": "b"}}) == LAYOUT
    with pytest.raises(LayoutError, match=r"edges\[0\]\.labels has 5 items"):
        check_layout({**LAYOUT, "edges": [{"id": "e", "sections": [], "labels": [{}] * 5}]})
    with pytest.raises(LayoutError, match=r"children\[0\]\.id is not an id"):
        check_layout({**LAYOUT, "children": [{"id": "", "x": 0, "y": 0}]})


def test_requests_at_once_all_find_the_shipped_layouts(tmp_path: Path) -> None:
    """The page asks for its lanes at once and the server reads in threads: the first request's
    read of the shipped file is waited for, not taken for empty."""
    keys = [f"{i:064x}" for i in range(12)]
    write_shipped(tmp_path / SHIPPED_NAME, dict.fromkeys(keys, LAYOUT))
    cache = LayoutCache(tmp_path / "user", [tmp_path / SHIPPED_NAME])

    async def steps(client: aiohttp.ClientSession, url: str) -> list[int]:
        answers = await asyncio.gather(*(_get(client, url, key) for key in keys))
        return [status for status, _ in answers]

    assert run(cache, steps) == [200] * len(keys)
