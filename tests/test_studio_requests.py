"""Bad requests to the studio's server, before and after the token check: each is answered 4xx
with a JSON message in words, never a 500 or a traceback (docs/security.md, "Faults and attacks
tested")."""

from __future__ import annotations

import asyncio
import json
from pathlib import Path
from typing import Any

import aiohttp
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from studio_support import Editor, snapshot

POSTS = ["edit", "undo", "redo", "save", "reload", "new", "recover", "complete", "run", "stop"]
KEYS = ["version", "ops", "force", "name", "action", "lane", "text", "cursor", "field", "track", "speed"]
OPS = ["add_component", "remove_component", "set_deployment", "add_port", "remove_port", "add_link",
       "remove_link", "add_lane", "remove_lane", "add_node", "set_node", "remove_node", "connect",
       "disconnect", "set_guard", "rename_node", "rename_lane", "rename_component", "set_layout"]
OP_KEYS = ["name", "kind", "impl", "settings", "component", "port", "feature", "from", "to", "id", "lane",
           "file", "node", "fields", "source", "target", "guard", "new_id", "new_name", "diagram",
           "positions"]


def _raw(url: str, data: bytes | str, headers: dict[str, str], method: str = "POST") -> tuple[int, str]:
    async def go() -> tuple[int, str]:
        async with aiohttp.ClientSession() as client, client.request(method, url, data=data,
                                                                     headers=headers) as response:
            return response.status, await response.text()

    return asyncio.run(go())


def _refused(status: int, text: str, expected: int, words: str) -> None:
    assert status == expected, (status, text[:300])
    body = json.loads(text)
    assert words in body["error"], body
    assert "Traceback" not in text and len(text) < 2000, text[:300]


JSON_TYPE = {"Content-Type": "application/json"}


def test_deep_json_a_bogus_charset_and_a_long_track_name_are_4xx_in_words(car: tuple[Path, Editor]) -> None:
    root, editor = car
    before = snapshot(root)
    url = f"{editor.url}api/edit"
    # before the token is looked at
    _refused(*_raw(url, "[" * 100_000 + "]" * 100_000, JSON_TYPE), 400, "not JSON: nested too deeply")
    _refused(*_raw(url, "{}", {"Content-Type": "application/json; charset=bogus"}), 415,
             "JSON in UTF-8, not charset=bogus")
    _refused(*_raw(url, b'{"token": "\xff"}', JSON_TYPE), 400, "not UTF-8")
    _refused(*_raw(url, "x" * (2 << 20), JSON_TYPE), 413, "request too large")
    _refused(*_raw(url, "NaN", JSON_TYPE), 400, "not JSON")
    # after it: a track name longer than the system's names (ENAMETOOLONG)
    status, text = _raw(f"{editor.url}api/run", json.dumps({"token": editor.token, "track": "x" * 5000}),
                        JSON_TYPE)
    _refused(status, text, 400, "no track 'xxxx")
    assert "File name too long" in text and "(5000 characters)" in text
    assert snapshot(root) == before


def test_odd_host_and_origin_headers_are_refused_in_words(car: tuple[Path, Editor]) -> None:
    _, editor = car
    port = editor.url.rstrip("/").rsplit(":", 1)[1]
    for headers in ({"Host": "["}, {"Host": f"[::1:{port}"}, {"Origin": "http://[::1"},
                    {"Origin": "null"}, {"Host": "evil.example"}):
        for method, path in (("GET", "/"), ("GET", "/api/files"), ("GET", "/ws"), ("POST", "/api/undo")):
            if path == "/" and "Origin" in headers:
                continue  # the page itself is served to any origin: it is the same for all
            status, text = _raw(f"{editor.url.rstrip('/')}{path}",
                                json.dumps({"token": editor.token}), {**JSON_TYPE, **headers}, method)
            assert status in (400, 403), (headers, path, status, text[:200])
            assert json.loads(text)["error"] and "Traceback" not in text


def test_a_new_models_name_of_another_type_is_refused_at_its_field(tmp_path: Path) -> None:
    editor = Editor(tmp_path / "new")
    try:
        for name in (1, ["a"], {"a": 1}, True):
            status, answer = editor.post("new", {"name": name})
            assert status == 400 and answer["fields"]["name"], (name, answer)
        assert not (tmp_path / "new").exists()
    finally:
        editor.thread.stop()


_values = st.recursive(st.none() | st.booleans() | st.integers(-3, 10**20) | st.floats(allow_nan=False)
                       | st.text(max_size=30) | st.sampled_from(["", "x" * 5000, "../x", "/etc/passwd",
                                                                 "a\x00b", "RaspberryPI", "main",
                                                                 "activities/main.yaml", "s_bend"]),
                       lambda inner: st.lists(inner, max_size=3) | st.dictionaries(st.text(max_size=8), inner,
                                                                                  max_size=3),
                       max_leaves=8)
_op = st.fixed_dictionaries({"op": st.sampled_from(OPS)},
                            optional={key: _values for key in OP_KEYS})
_bodies = st.fixed_dictionaries({}, optional={key: _values for key in KEYS}
                                ) | st.fixed_dictionaries({"ops": st.lists(_op, max_size=3)},
                                                          optional={"version": _values})


@settings(max_examples=300, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture,
                                                                   HealthCheck.too_slow])
@given(route=st.sampled_from(POSTS), body=_bodies, with_token=st.booleans())
def test_any_json_body_on_any_route_is_answered_without_a_500(car: tuple[Path, Editor], route: str,
                                                             body: dict[str, Any], with_token: bool) -> None:
    _, editor = car
    if route == "run":  # a run of the car starts a simulator: ask only what is refused before it
        body = {**body, "speed": 1000}
    sent = {**body, "token": editor.token} if with_token else body
    status, text = _raw(f"{editor.url}api/{route}", json.dumps(sent), JSON_TYPE)
    assert status < 500, (route, sent, text[:500])
    if status >= 400:
        answer = json.loads(text)
        assert isinstance(answer.get("error"), str) and answer["error"], answer
    if not with_token:
        assert status in (400, 403), (route, status, text[:200])


def test_a_studio_that_edits_refuses_to_listen_beyond_loopback(tmp_path: Path) -> None:
    """Editing needs the Host check, which only a loopback bind can make: a server given a
    workspace and a non-loopback host does not start (the command never builds one)."""
    from umlbot.base.errors import ConfigError
    from umlbot.studio.api import EditApi
    from umlbot.studio.data import StudioData
    from umlbot.studio.server import StudioServer
    from umlbot.studio.workspace import Workspace

    data = StudioData(mode="live", robot="car", source="x", model=None, diagnostics=[])
    server = StudioServer(data, host="0.0.0.0", port=0, allow_remote=True)
    server.api = EditApi(Workspace(tmp_path / "new"))
    with pytest.raises(ConfigError, match=r"edits a model only on a loopback --host, not 0\.0\.0\.0"):
        asyncio.run(server.start())


def test_the_library_answer_does_not_hold_up_the_pages_other_first_requests(
        car: tuple[Path, Editor], monkeypatch: pytest.MonkeyPatch) -> None:
    """`/api/library` is made once (every implementation's settings schema: seconds on a busy
    machine), off the event loop: the page's layout lookup and files are answered meanwhile."""
    import threading
    import time

    import umlbot.studio.api as api

    _, editor = car
    release = threading.Event()
    made = api._library()

    def slow() -> dict[str, Any]:
        release.wait(10.0)
        return made

    monkeypatch.setattr(api, "_library", slow)

    async def go() -> tuple[float, float, dict[str, Any]]:
        async with aiohttp.ClientSession() as client:
            library = asyncio.ensure_future(client.get(f"{editor.url}api/library"))
            await asyncio.sleep(0.2)  # the library's request is in, waiting for the slow answer
            started = time.monotonic()
            async with client.get(f"{editor.url}api/files") as files:
                assert files.status == 200
            async with client.get(f"{editor.url}api/layout/{'0' * 64}") as layout:
                assert layout.status == 200  # asked and answered: nothing kept under that key
                assert (await layout.json())["layout"] is None
            others = time.monotonic() - started
            assert not library.done()
            release.set()
            async with await library as answer:
                return others, time.monotonic() - started, await answer.json()

    others, total, answer = asyncio.run(go())
    assert others < 5.0 and total >= others  # not behind the library's answer (held for 10 s)
    assert answer == json.loads(json.dumps(made))
