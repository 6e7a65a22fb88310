"""Test helpers for umlbot studio: a `umlbot studio` child process, a WebSocket reader, and a studio
editing a folder in this process (`Editor`) with a client for its requests."""

from __future__ import annotations

import asyncio
import json
import os
import re
import subprocess
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import aiohttp
from playwright.sync_api import Browser, Page, sync_playwright
from robot_run import umlbot_argv

from umlbot.studio.api import EditApi
from umlbot.studio.data import StudioData
from umlbot.studio.server import StudioServer, StudioThread
from umlbot.studio.workspace import Workspace

URL_LINE = re.compile(r"umlbot studio: (http://\S+)")
REPO = Path(__file__).resolve().parent.parent
OUT = REPO / "out"
CHROMIUM = "/usr/bin/chromium"
#: as root and on a closed network: no sandbox, no background traffic (docs/studio.md, tests)
CHROMIUM_ARGS = ["--no-sandbox", "--disable-gpu", "--disable-background-networking",
                 "--disable-component-update", "--disable-sync", "--no-first-run"]
#: a one-file model whose one action calls a feature the motor does not have
BROKEN_MODEL = (
    "name: bad\ncomponents:\n  Motor: {kind: actuator}\n"
    "lanes:\n  - lane: Motor\n    nodes:\n"
    "      - {id: start, kind: start}\n"
    "      - {id: go, kind: action, call: Motor.speed(3)}\n"
    "      - {id: end, kind: end}\n"
    "deployment:\n  driver: mock\n  components:\n"
    "    Motor: {impl: l298n, settings: {in1: 22, in2: 23}}\n"
)


@contextmanager
def chromium() -> Iterator[Browser]:
    """Debian's Chromium driven by Playwright (never a downloaded browser)."""
    if not Path(CHROMIUM).exists():
        raise AssertionError(f"{CHROMIUM} is required: apt-get install chromium (make test installs it)")
    with sync_playwright() as pw:
        launched = pw.chromium.launch(executable_path=CHROMIUM, args=CHROMIUM_ARGS)
        try:
            yield launched
        finally:
            launched.close()


def shot(page: Page, name: str) -> None:
    """A screenshot under out/ for people to look at."""
    OUT.mkdir(exist_ok=True)
    page.screenshot(path=str(OUT / name))


class StudioProc:
    """`umlbot studio ARGS` (or `umlbot sim … --studio`) as a child process; `url` once it listens."""

    def __init__(self, args: list[str], workdir: Path, broker_url: str | None = None,
                 timeout: float = 60.0, prefix: list[str] | None = None) -> None:
        env = {k: v for k, v in os.environ.items() if k not in ("UMLBOT_ROBOT", "UMLBOT_BROKER")}
        if broker_url is not None:
            env["UMLBOT_BROKER"] = broker_url
        self.stderr_path = workdir / f"studio-{time.monotonic_ns()}.log"
        with self.stderr_path.open("wb") as err:
            self.popen = subprocess.Popen([*(prefix or []), *umlbot_argv(*args)], stdout=subprocess.PIPE,
                                          stderr=err, cwd=workdir, env=env, text=True)
        self.lines: list[str] = []
        self.url = self._wait_url(timeout)

    def _wait_url(self, timeout: float) -> str:
        assert self.popen.stdout is not None
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            line = self.popen.stdout.readline()
            if not line:
                break
            self.lines.append(line.rstrip("\n"))
            match = URL_LINE.search(line)
            if match:
                return match.group(1)
        self.stop()
        raise AssertionError(f"studio printed no URL: {self.lines}\n{self.log_text()[-3000:]}")

    def wait_line(self, text: str) -> None:
        """Read stdout until a line holds `text` (AssertionError when it ends first)."""
        assert self.popen.stdout is not None
        while not any(text in line for line in self.lines):
            line = self.popen.stdout.readline()
            assert line, (f"no line with {text!r}", self.lines, self.log_text()[-3000:])
            self.lines.append(line.rstrip("\n"))

    def log_text(self) -> str:
        return self.stderr_path.read_text(encoding="utf-8", errors="replace")

    def stop(self, timeout: float = 15.0) -> int:
        if self.popen.poll() is None:
            self.popen.terminate()
            try:
                self.popen.wait(timeout)
            except subprocess.TimeoutExpired:
                self.popen.kill()
                self.popen.wait(5)
        if self.popen.stdout is not None:
            self.popen.stdout.close()
        return self.popen.returncode


@contextmanager
def studio(args: list[str], workdir: Path, broker_url: str | None = None,
           prefix: list[str] | None = None) -> Iterator[StudioProc]:
    """`umlbot studio ARGS` as a child process (run by the command `prefix` when given)."""
    proc = StudioProc(args, workdir, broker_url, prefix=prefix)
    try:
        yield proc
    finally:
        proc.stop()


def read_frames(url: str, until: Callable[[list[dict[str, Any]]], bool], timeout: float = 20.0,
                headers: dict[str, str] | None = None) -> list[dict[str, Any]]:
    """Frames of one WebSocket session (hello first) until `until(frames)` holds; AssertionError on
    time-out."""

    async def session() -> list[dict[str, Any]]:
        frames: list[dict[str, Any]] = []
        deadline = time.monotonic() + timeout
        async with aiohttp.ClientSession() as client, client.ws_connect(url.rstrip("/") + "/ws",
                                                                           headers=headers) as ws:
            while not until(frames):
                remaining = deadline - time.monotonic()
                if remaining <= 0:
                    raise AssertionError(f"condition not met within {timeout} s; {len(frames)} frames")
                try:
                    message = await ws.receive(timeout=remaining)
                except TimeoutError:
                    continue
                if message.type != aiohttp.WSMsgType.TEXT:
                    raise AssertionError(f"socket ended: {message.type}")
                frames.append(json.loads(message.data))
        return frames

    return asyncio.run(session())


def events_of(frames: list[dict[str, Any]], kind: str | None = None) -> list[dict[str, Any]]:
    """Every event of the `events` frames (of one type when `kind` is given), in order."""
    out = [e for f in frames if f["type"] == "events" for e in f["events"]]
    return [e for e in out if kind is None or e["type"] == kind]


class StudioClient:
    """A client for the editing requests of the studio at `url`, with its write token."""

    def __init__(self, url: str, token: str) -> None:
        self.url = url
        self.token = token

    def post(self, name: str, body: dict[str, Any], headers: dict[str, str] | None = None,
             token: str | None = None) -> tuple[int, dict[str, Any]]:
        async def go() -> tuple[int, dict[str, Any]]:
            async with aiohttp.ClientSession() as client, client.post(
                    f"{self.url}api/{name}", json={"token": token or self.token, **body},
                    headers=headers) as resp:
                text = await resp.text()
                return resp.status, json.loads(text) if text.startswith("{") else {"text": text}

        return asyncio.run(go())

    def get(self, name: str) -> dict[str, Any]:
        async def go() -> dict[str, Any]:
            async with aiohttp.ClientSession() as client, client.get(f"{self.url}api/{name}") as resp:
                assert resp.status == 200
                result: dict[str, Any] = await resp.json()
                return result

        return asyncio.run(go())


class Editor(StudioClient):
    """A studio editing `root`, served on a free port in this process, and a client for it."""

    def __init__(self, root: Path) -> None:
        self.workspace = Workspace(root)
        data = StudioData(mode="live", robot="car", source=str(root), model=None, diagnostics=[])
        self.server = StudioServer(data, port=0)
        api = EditApi(self.workspace)
        self.server.api = api
        data.edit = api.hello
        self.thread = StudioThread(self.server)
        super().__init__(self.thread.start(), self.workspace.token)


def snapshot(root: Path) -> dict[str, bytes]:
    """Every file under `root` (relative path -> bytes)."""
    return {p.relative_to(root).as_posix(): p.read_bytes() for p in sorted(root.rglob("*")) if p.is_file()}
