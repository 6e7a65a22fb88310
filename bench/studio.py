"""Studio benchmark: how late the page shows a node, and how smooth it stays under load.

Both parts run a real broker (Mosquitto, or the embedded amqtt with --broker amqtt), a real
`umlbot studio` process and Debian's Chromium driven by Playwright; the page measures itself
(`window.__studio`, docs/studio.md):

- **latency**: the reference car (`models/robot_car`) runs on mock services under a real
  `umlbot run`; for each trace event the page applies, it records the time from the node's end
  (the orchestrator's clock, the event's own `time`) to the animation frame that highlighted it.
  Beside it, the part before the studio (`trace_p50_ms`, `trace_p99_ms`: a node's end to its
  trace message at a subscriber on the same broker), the part before the page's frame
  (`socket_p50_ms`, `socket_p99_ms`: a node's end to the studio's message that carried it, as the
  page's main thread takes it) and the trace messages per second.
  Targets: p50 <= 50 ms, p99 <= 200 ms.
- **load**: a generated model of `--nodes` activity nodes in one activity diagram (20 swimlanes of
  100 nodes), shown in the page, while a publisher sends `--rate` trace events per second on the
  trace topic in the orchestrator's batched form (a JSON array every 20 ms) for `--seconds`.
  The page records every frame's duration (requestAnimationFrame to requestAnimationFrame) and
  the browser its long tasks (main-thread work over 50 ms: the page's own code); the machine's
  load average is printed beside them. Target: no frame over 100 ms.
- **edit**: the same generated model of `--nodes` nodes opened for editing by a real `umlbot
  studio` in Chromium; `--edits` edits made by the page (`window.__studio.edit.send`, the path
  of the properties panel: a datastore value, a guard made bad and good again, a call), each on a
  node the view shows first; the page times each from its request leaving to the end of the
  animation frame that drew the new diagram with the node's diagnostic
  (`window.__studio.edit.timings`), split into the server's answer and the drawing; after each,
  a bare `check_model` of the same files is timed in this process (the compiler's share, under
  the same load). Then the server's side alone in this process (`Workspace.edit` and its JSON)
  for the same edits, with the studio's incremental check and alternately with a check from
  scratch (`server_edit_*`, `server_edit_full_*`, `incremental_check_*`). Target: p50 <= 300 ms.
  No broker.

- **first**: the reference car opened in a new browser context (`--first-samples` times, no cached
  script, as a new user's first open); the page records, in every animation frame from the
  navigation's start, when its progress indication ("Opening the model…") first shows and when
  the first diagram's nodes are drawn (the page's DOMContentLoaded beside them as the baseline),
  and the page's own split of that diagram's time: ELK's layout (in its worker) and the drawing.
  As a fresh clone opens it (an empty user layout cache, the layouts shipped beside the model),
  alternated with the same open with the layout cache off (`elk_baseline`: ELK every time).
  Target: the first diagram <= 1 000 ms at p50, the progress indication shown before it. No broker.

The last output line is one JSON object {"latency": {...}, "load": {...}, "edit": {...},
"first": {...}}. Exit 1 when a target is missed. `--parts edit` runs only the edit part (also
`latency`, `load`, `first`).

    python bench/studio.py [--nodes 2000] [--rate 2000] [--seconds 10] [--broker mosquitto|amqtt]
                           [--edits 30] [--parts latency,load,edit,first] [--first-samples 5]
"""

from __future__ import annotations

import argparse
import contextlib
import gc
import json
import os
import random
import re
import statistics
import subprocess
import sys
import tempfile
import threading
import time
from collections.abc import Iterator
from contextlib import ExitStack, contextmanager
from pathlib import Path
from typing import Any

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

import paho.mqtt.client as mqtt
from compile import DEPLOYMENT, MODEL, lane_text  # bench/compile.py: the generated lanes
from orchestrator import run_broker  # Mosquitto with set_tcp_nodelay, as deployed
from paho.mqtt.enums import CallbackAPIVersion
from playwright.sync_api import Page, sync_playwright

REPO = Path(__file__).resolve().parent.parent
CAR = REPO / "models" / "robot_car"
CHROMIUM = "/usr/bin/chromium"
CHROMIUM_ARGS = ["--no-sandbox", "--disable-gpu", "--disable-background-networking",
                 "--disable-component-update", "--disable-sync", "--no-first-run"]
LANE_NODES = 100
BATCH_S = 0.02
TARGETS = {"latency_p50_ms": 50.0, "latency_p99_ms": 200.0, "max_frame_ms": 100.0, "edit_p50_ms": 300.0,
           "first_diagram_ms": 1000.0}


def umlbot(*args: str) -> list[str]:
    return [sys.executable, "-c", "from umlbot.cli import main; main()", *args]


def percentile(values: list[float], q: float) -> float:
    ordered = sorted(values)
    return ordered[min(len(ordered) - 1, max(0, round(q / 100 * len(ordered)) - 1))]


def big_model(root: Path, nodes: int) -> Path:
    """A model folder whose one activity file holds `nodes` nodes in swimlanes of 100."""
    (root / "activities").mkdir(parents=True)
    (root / "model.yaml").write_text(MODEL, encoding="utf-8")
    (root / "deployment.yaml").write_text(DEPLOYMENT, encoding="utf-8")
    lanes = max(1, nodes // LANE_NODES)
    parts = ["lanes:"]
    for index in range(lanes):
        name = "RaspberryPI" if index == 0 else f"Helper{index}"
        callee = f"Helper{index + 1}" if index + 1 < lanes else None
        text = lane_text(name, LANE_NODES, callee)
        parts.append("\n".join(("  - " if i == 0 else "    ") + line
                               for i, line in enumerate(text.rstrip("\n").splitlines())))
    (root / "activities" / "all.yaml").write_text("\n".join(parts) + "\n", encoding="utf-8")
    return root


@contextmanager
def child(argv: list[str], env: dict[str, str], log: Path) -> Iterator[subprocess.Popen[str]]:
    with log.open("w") as err:
        proc = subprocess.Popen(argv, stdout=subprocess.PIPE, stderr=err, env=env, text=True)
    try:
        yield proc
    finally:
        if proc.poll() is None:
            proc.terminate()
            try:
                proc.wait(15)
            except subprocess.TimeoutExpired:
                proc.kill()
                proc.wait(5)
        if proc.stdout is not None:
            proc.stdout.close()


def studio_url(proc: subprocess.Popen[str], timeout: float = 60.0) -> str:
    assert proc.stdout is not None
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        line = proc.stdout.readline()
        match = re.search(r"umlbot studio: (http://\S+)", line)
        if match:
            return match.group(1)
        if not line and proc.poll() is not None:
            break
    raise RuntimeError("umlbot studio did not print its URL")


#: the page's own long tasks (main-thread work over 50 ms), to tell its code from a starved machine
LONG_TASKS = """
window.__longTasks = [];
new PerformanceObserver((list) => {
  for (const entry of list.getEntries()) window.__longTasks.push(entry.duration);
}).observe({type: "longtask", buffered: true});
"""


def open_page(browser: Any, url: str, diagram: str | None = None) -> Page:
    page: Page = browser.new_page(viewport={"width": 1600, "height": 1000})
    page.add_init_script(LONG_TASKS)
    page.goto(url + (f"#diagram={diagram}" if diagram else ""))
    page.wait_for_function("window.__studio && window.__studio.ready === true", timeout=120_000)
    return page


class TraceWatch:
    """The trace as a subscriber on the same broker sees it while the page measures: each event's
    time from its node's end to the message's arrival (the orchestrator's batching and the
    broker: the part of the page's latency before the studio), and the messages per second."""

    def __init__(self, broker_url: str, robot: str) -> None:
        self.delays_ms: list[float] = []
        self.messages = 0
        self._lock = threading.Lock()
        port = int(broker_url.rsplit(":", 1)[1])
        self._client = mqtt.Client(CallbackAPIVersion.VERSION2, client_id=f"bench-trace-{os.getpid()}")
        self._client.on_message = self._message
        self._client.connect("127.0.0.1", port, 30)
        self._client.subscribe(f"umlbot/{robot}/orchestrator/trace")
        self._client.loop_start()

    def _message(self, _client: Any, _userdata: Any, message: Any) -> None:
        now = time.time()
        batch = json.loads(message.payload)
        with self._lock:
            self.messages += 1
            for event in batch if isinstance(batch, list) else [batch]:
                self.delays_ms.append((now - event["end"]) * 1000.0)

    def restart(self) -> float:
        with self._lock:
            self.delays_ms.clear()
            self.messages = 0
        return time.monotonic()

    def close(self) -> None:
        self._client.loop_stop()
        self._client.disconnect()


def measure_latency(browser: Any, broker_url: str, seconds: float, workdir: Path) -> dict[str, Any]:
    env = {**os.environ, "UMLBOT_BROKER": broker_url, "UMLBOT_LOG_LEVEL": "WARNING"}
    compiled = workdir / "car.json"
    subprocess.run(umlbot("compile", str(CAR), "-o", str(compiled)), check=True, env=env, timeout=120)
    with ExitStack() as stack:
        for kind in ("motor", "sonar", "servo", "gpio"):
            argv = umlbot("service", kind, "--deploy", str(CAR / "deployment.yaml"), "--driver", "mock",
                          "--robot", "car")
            stack.enter_context(child(argv, env, workdir / f"{kind}.log"))
        studio = stack.enter_context(child(umlbot("studio", str(CAR), "--port", "0", "--robot", "car"), env,
                                           workdir / "studio.log"))
        page = open_page(browser, studio_url(studio))
        watch = TraceWatch(broker_url, "car")
        stack.callback(watch.close)
        with child(umlbot("run", str(compiled), "--robot", "car"), env, workdir / "run.log"):
            page.wait_for_function("window.__studio.latencies.length > 0", timeout=60_000)
            page.evaluate("window.__studio.latencies.length = 0; window.__studio.arrivals.length = 0")
            began = watch.restart()
            time.sleep(seconds)
            latencies: list[float] = page.evaluate("window.__studio.latencies.slice()")
            arrivals: list[float] = page.evaluate("window.__studio.arrivals.slice()")
            applied: int = page.evaluate("window.__studio.applied")
            trace = list(watch.delays_ms)
            messages_per_s = watch.messages / (time.monotonic() - began)
        page.close()
    return {"samples": len(latencies), "applied": applied,
            "latency_p50_ms": round(statistics.median(latencies), 1),
            "latency_p99_ms": round(percentile(latencies, 99), 1),
            "latency_max_ms": round(max(latencies), 1),
            # the share of it before the studio: node end -> trace message at a subscriber
            "trace_p50_ms": round(statistics.median(trace), 1) if trace else None,
            "trace_p99_ms": round(percentile(trace, 99), 1) if trace else None,
            # the share before the page's frame: node end -> the studio's message taken by the page
            "socket_p50_ms": round(statistics.median(arrivals), 1) if arrivals else None,
            "socket_p99_ms": round(percentile(arrivals, 99), 1) if arrivals else None,
            "trace_messages_per_s": round(messages_per_s, 1)}


def publish_load(broker_url: str, lanes: dict[str, list[tuple[str, str]]], rate: float, seconds: float,
                 stop: threading.Event) -> int:
    """Publish `rate` trace events/s (one JSON array per 20 ms) for `seconds`; returns how many."""
    port = int(broker_url.rsplit(":", 1)[1])
    client = mqtt.Client(CallbackAPIVersion.VERSION2, client_id=f"bench-studio-{os.getpid()}")
    client.connect("127.0.0.1", port, 30)
    client.loop_start()
    rng = random.Random(7)
    pool = [(lane, node, kind) for lane, nodes in lanes.items() for node, kind in nodes]
    per_batch = max(1, round(rate * BATCH_S))
    sent = 0
    seq = 0
    began = time.monotonic()
    next_at = began
    try:
        while not stop.is_set() and time.monotonic() - began < seconds:
            now = time.time()
            batch = []
            for _ in range(per_batch):
                lane, node, kind = rng.choice(pool)
                seq += 1
                duration = rng.uniform(0.0005, 0.02)
                batch.append({"lane": lane, "node": node, "kind": kind, "start": now - duration, "end": now,
                              "duration_ms": round(duration * 1000, 3), "level": "info", "detail": node,
                              "seq": seq, **({"value": seq} if kind == "datastore" else {})})
            client.publish("umlbot/bench/orchestrator/trace", json.dumps(batch), qos=0)
            sent += len(batch)
            next_at += BATCH_S
            time.sleep(max(0.0, next_at - time.monotonic()))
    finally:
        client.loop_stop()
        client.disconnect()
    return sent


def measure_load(browser: Any, broker_url: str, nodes: int, rate: float, seconds: float,
                 workdir: Path) -> dict[str, Any]:
    from umlbot.compiler.api import compile_model

    model = big_model(workdir / "big", nodes)
    compiled = compile_model(model)
    lanes = {name: [(node.id, str(node.kind)) for node in lane.nodes.values()]
             for name, lane in compiled.lanes.items()}
    total_nodes = sum(len(v) for v in lanes.values())
    env = {**os.environ, "UMLBOT_BROKER": broker_url, "UMLBOT_LOG_LEVEL": "WARNING"}
    with child(umlbot("studio", str(model), "--port", "0", "--robot", "bench"), env,
               workdir / "studio-big.log") as studio:
        page = open_page(browser, studio_url(studio), diagram="activity-all")
        # all 2 000 nodes on screen (Fit): a big diagram opens readable at its start, one lane shown
        page.keyboard.press("f")
        shown = page.locator("g.node").count()
        page.evaluate("window.__studio.frames.length = 0; window.__longTasks.length = 0")
        load_before = os.getloadavg()[0]
        stop = threading.Event()
        sent = publish_load(broker_url, lanes, rate, seconds, stop)
        time.sleep(1.0)  # the last frames reach the page
        frames: list[float] = page.evaluate("window.__studio.frames.slice()")
        applied: int = page.evaluate("window.__studio.applied")
        long_tasks: list[float] = page.evaluate("window.__longTasks.slice()")
        page.screenshot(path=str(REPO / "out" / "studio-bench-2000.png"))
        page.close()
    return {"nodes": total_nodes, "nodes_shown": shown, "rate_per_s": rate, "seconds": seconds, "sent": sent,
            "applied": applied, "frames": len(frames),
            "frame_p50_ms": round(statistics.median(frames), 1) if frames else None,
            "frame_p99_ms": round(percentile(frames, 99), 1) if frames else None,
            "max_frame_ms": round(max(frames), 1) if frames else None,
            "frames_over_100_ms": sum(1 for f in frames if f > 100.0),
            "long_tasks": len(long_tasks),
            "max_long_task_ms": round(max(long_tasks), 1) if long_tasks else 0.0,
            "load_average": round(max(load_before, os.getloadavg()[0]), 1)}


def edit_ops(index: int, nodes: int = 2000) -> list[dict[str, Any]]:
    """The `index`-th edit of the edit part on the model of `nodes` nodes: a datastore value; a
    guard made bad (a diagnostic on its node); a guard made good with a call changed in the same
    batch. Each on one of the called lanes in turn (the start lane on a model of one lane)."""
    lanes = [f"Helper{i}" for i in range(1, min(19, max(1, nodes // LANE_NODES)))] or ["RaspberryPI"]
    lane = lanes[index % len(lanes)]
    step = index % 3
    if step == 0:
        return [{"op": "set_node", "lane": lane, "id": "b3_x", "fields": {"value": f"{index} * 2 + 1"}}]
    if step == 1:  # a guard that does not type-check: a diagnostic on the node
        return [{"op": "set_guard", "lane": lane, "source": "b2_choose", "target": "b2_fork",
                 "guard": "d2 > 'far'"}]
    return [{"op": "set_guard", "lane": lane, "source": "b2_choose", "target": "b2_fork",
             "guard": "d2 > 20 and not Application.exit"},
            {"op": "set_node", "lane": lane, "id": "b5_wait", "fields": {"call": f"usleep(x5 * {index})"}}]


def edited_node(index: int, nodes: int) -> tuple[str, str]:
    """The (lane, node) the `index`-th edit of `edit_ops` is about (the view shows it first)."""
    ops = edit_ops(index, nodes)
    return str(ops[0]["lane"]), str(ops[0].get("id") or ops[0]["source"])


#: when the page first shows its progress indication and its first diagram's nodes (ms since the
#: navigation started), looked at in every animation frame
FIRST_DRAWN = """
window.__first = {};
const look = () => {
  const t = performance.now();
  const p = document.querySelector("#canvas-progress");
  if (window.__first.progress === undefined && p && !p.hidden && p.getBoundingClientRect().height > 0)
    window.__first.progress = t;
  const node = document.querySelector("svg.diagram g.node");
  if (node) {
    window.__first.diagram = t;
    window.__first.id = node.closest("svg.diagram").dataset.diagram;
  } else requestAnimationFrame(look);
};
requestAnimationFrame(look);
"""


def measure_first(browser: Any, samples: int, workdir: Path) -> dict[str, Any]:
    """How long after the page opens (navigation start) the reference car's first diagram is drawn,
    and when the progress indication shows before it; each sample in a new browser context (no
    cached script: a new user's first open). The page's own DOMContentLoaded is the baseline.
    Two studios side by side, their samples alternated (the same load): one as a fresh clone has it
    (an empty user layout cache, the layouts shipped beside the model: what the target is about)
    and one with the layout cache off (ELK lays out every open: `elk_baseline`)."""
    base = {k: v for k, v in os.environ.items() if k not in ("UMLBOT_ROBOT", "UMLBOT_BROKER")}
    base["UMLBOT_BROKER"] = "mqtt://127.0.0.1:1"  # no broker: the drawing only
    envs = {"cached": {**base, "XDG_CACHE_HOME": str(workdir / "xdg-first")},
            "elk": {**base, "UMLBOT_LAYOUT_CACHE": "off"}}
    runs: dict[str, list[dict[str, Any]]] = {"cached": [], "elk": []}
    load_before = os.getloadavg()[0]
    with contextlib.ExitStack() as stack:
        urls = {name: studio_url(stack.enter_context(child(umlbot("studio", str(CAR), "--port", "0"), env,
                                                           workdir / f"studio-first-{name}.log")))
                for name, env in envs.items()}
        for _ in range(samples):
            for name, url in urls.items():
                runs[name].append(_first_sample(browser, url))
    out = _first_summary(runs["cached"])
    out["layouts"] = runs["cached"][-1]["layouts"]
    out["elk_baseline"] = _first_summary(runs["elk"])
    out["first_diagram_p50_ratio_to_elk"] = round(out["first_diagram_p50_ms"]
                                                  / out["elk_baseline"]["first_diagram_p50_ms"], 3)
    out["load_average"] = [round(load_before, 2), round(os.getloadavg()[0], 2)]
    return out


def _first_sample(browser: Any, url: str) -> dict[str, Any]:
    context = browser.new_context(viewport={"width": 1600, "height": 1000})
    page = context.new_page()
    page.add_init_script(FIRST_DRAWN)
    said: list[str] = []  # the page's own "studio: <id> laid out in N ms, drawn in M ms"
    page.on("console", lambda message, said=said: said.append(message.text))
    page.goto(url)
    page.wait_for_function("window.__first && window.__first.diagram !== undefined", timeout=120_000)
    first: dict[str, Any] = page.evaluate("window.__first")
    dcl = page.evaluate("performance.getEntriesByType('navigation')[0].domContentLoadedEventEnd")
    layouts = page.evaluate("window.__studio.layouts ? {...window.__studio.layouts} : null")
    # the layout cache's first request (the first diagram's lane): when it left, how long it took
    lookup = page.evaluate("(() => { const e = performance.getEntriesByType('resource')"
                           ".find(r => r.name.includes('/api/layout/'));"
                           " return e ? [e.startTime, e.duration] : null; })()")
    said_re = rf"studio: {first['id']} laid out in (\d+) ms, drawn in (\d+) ms"
    split = next((m for m in (re.search(said_re, text) for text in said) if m), None)
    context.close()
    return {"diagram": first["id"], "progress_ms": round(first.get("progress", -1), 1),
            "first_diagram_ms": round(first["diagram"], 1),
            "dom_content_loaded_ms": round(dcl, 1),
            "layout_ms": int(split.group(1)) if split else None,
            "render_ms": int(split.group(2)) if split else None,
            "layout_lookup_at_ms": round(lookup[0], 1) if lookup else None,
            "layout_lookup_ms": round(lookup[1], 1) if lookup else None,
            "layouts": layouts}


def _first_summary(runs: list[dict[str, Any]]) -> dict[str, Any]:
    drawn = [r["first_diagram_ms"] for r in runs]
    return {"samples": [{k: v for k, v in r.items() if k != "layouts"} for r in runs],
            "diagram": runs[0]["diagram"],
            "first_diagram_p50_ms": round(statistics.median(drawn), 1),
            "first_diagram_max_ms": round(max(drawn), 1),
            "progress_max_ms": round(max(r["progress_ms"] for r in runs), 1),
            "progress_before_diagram": all(0 <= r["progress_ms"] < r["first_diagram_ms"] for r in runs)}


def measure_edit(browser: Any, nodes: int, edits: int, workdir: Path) -> dict[str, Any]:
    """Edit-to-diagnostics-shown time in the page (Chromium) on a model of `nodes` nodes, its
    answer and drawing parts, and bare checks."""
    from umlbot.compiler.api import check_model

    root = big_model(workdir / f"edit{nodes}", nodes)
    env = {k: v for k, v in os.environ.items() if k not in ("UMLBOT_ROBOT", "UMLBOT_BROKER")}
    env["UMLBOT_BROKER"] = "mqtt://127.0.0.1:1"  # nothing to follow: the broker is not needed
    checks: list[float] = []
    errors_seen = 0
    load_before = os.getloadavg()[0]
    with child(umlbot("studio", str(root), "--port", "0"), env, workdir / "studio-edit.log") as proc:
        page = open_page(browser, studio_url(proc), diagram="activity-all")
        page.wait_for_function("!!window.__studio.edit", timeout=60_000)
        for index in range(edits):
            lane, node = edited_node(index, nodes)
            page.evaluate("([lane, node]) => window.__studio.reveal(lane, node)", [lane, node])
            page.wait_for_timeout(300)  # the view settles, as between a person's edits
            ok = page.evaluate("ops => window.__studio.edit.send(ops)", edit_ops(index, nodes))
            if not ok:
                raise RuntimeError(f"edit {index} refused: {page.evaluate('window.__studio.edit.errors')}")
            page.wait_for_function("() => { const t = window.__studio.edit.timings; "
                                   "return t.length > 0 && t[t.length - 1].shown !== undefined; }",
                                   timeout=60_000)
            if index % 3 == 1:  # the bad guard's message is on its node, in the page
                selector = f'g.node[data-lane="{lane}"][data-node="b2_choose"]'
                errors_seen += page.evaluate("s => document.querySelector(s)?.classList.contains('error')",
                                             selector)
            # the compiler alone on the same files, right after (the same load on the machine)
            started = time.perf_counter()
            check_model(root)
            checks.append((time.perf_counter() - started) * 1000)
        timings: list[dict[str, float]] = page.evaluate("window.__studio.edit.timings.slice()")
        page.screenshot(path=str(REPO / "out" / "studio-bench-edit.png"))
        page.close()
    shown = [t["shown"] - t["sent"] for t in timings]
    answered = [t["answered"] - t["sent"] for t in timings]
    drawn = [t["shown"] - t["answered"] for t in timings]
    return {"nodes": nodes, "edits": len(timings), "bad_guards_shown": errors_seen,
            "edit_p50_ms": round(statistics.median(shown), 1),
            "edit_p99_ms": round(percentile(shown, 99), 1),
            "answer_p50_ms": round(statistics.median(answered), 1),
            "draw_p50_ms": round(statistics.median(drawn), 1),
            "draw_p99_ms": round(percentile(drawn, 99), 1),
            "check_p50_ms": round(statistics.median(checks), 1),
            "check_p99_ms": round(percentile(checks, 99), 1),
            **server_edits(root, edits, nodes),
            "load_average": round(max(load_before, os.getloadavg()[0]), 1)}


class _FullCheck:
    """The studio's check before issue 28: every edit checks the whole working copy from scratch."""

    def check(self, path: Path, files: Any = None) -> Any:
        from umlbot.compiler.api import check_model

        return check_model(path, files=files)


def server_edits(root: Path, edits: int, nodes: int) -> dict[str, float]:
    """The server's side of the same edits in this process (`Workspace.edit` and the answer's
    JSON, no HTTP), with the incremental check and, alternately in the same minutes, with a check
    from scratch (the raw baseline); and the incremental check alone (`check_*`)."""
    from umlbot.studio.workspace import Workspace

    incremental, full = Workspace(root), Workspace(root)
    full.checker = _FullCheck()  # type: ignore[assignment]
    checks: list[float] = []
    original = incremental.checker.check

    def timed(*args: Any, **kwargs: Any) -> Any:
        started = time.perf_counter()
        try:
            return original(*args, **kwargs)
        finally:
            checks.append((time.perf_counter() - started) * 1000)

    incremental.checker.check = timed  # type: ignore[method-assign]
    times: dict[str, list[float]] = {"incremental": [], "full": []}
    for ws in (incremental, full):
        ws.check()
    checks.clear()
    gc.collect()
    gc.freeze()  # as the studio's server does once started (`StudioServer.start`)
    try:
        for index in range(edits):
            for name, ws in (("incremental", incremental), ("full", full)):
                started = time.perf_counter()
                json.dumps(ws.edit(ws.version, edit_ops(index, nodes)))
                times[name].append((time.perf_counter() - started) * 1000)
    finally:
        gc.unfreeze()
    return {"server_edit_p50_ms": round(statistics.median(times["incremental"]), 1),
            "server_edit_p99_ms": round(percentile(times["incremental"], 99), 1),
            "server_edit_full_p50_ms": round(statistics.median(times["full"]), 1),
            "server_edit_full_p99_ms": round(percentile(times["full"], 99), 1),
            "incremental_check_p50_ms": round(statistics.median(checks), 1),
            "incremental_check_p99_ms": round(percentile(checks, 99), 1)}


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--nodes", type=int, default=2000)
    parser.add_argument("--rate", type=float, default=2000.0)
    parser.add_argument("--seconds", type=float, default=10.0)
    parser.add_argument("--broker", choices=["mosquitto", "amqtt"], default="mosquitto")
    parser.add_argument("--edits", type=int, default=30)
    parser.add_argument("--parts", default="latency,load,edit,first",
                        help="comma-separated parts to run: latency, load, edit, first")
    parser.add_argument("--first-samples", type=int, default=5)
    args = parser.parse_args()
    parts = {p.strip() for p in args.parts.split(",") if p.strip()}
    unknown = parts - {"latency", "load", "edit", "first"}
    if unknown:
        parser.error(f"unknown part(s): {', '.join(sorted(unknown))}")
    (REPO / "out").mkdir(exist_ok=True)
    result: dict[str, Any] = {"broker": args.broker, "targets": TARGETS}
    ok = True
    with tempfile.TemporaryDirectory() as tmp, sync_playwright() as pw:
        browser = pw.chromium.launch(executable_path=CHROMIUM, args=CHROMIUM_ARGS)
        try:
            if parts & {"latency", "load"}:
                with run_broker(args.broker) as url:
                    if "latency" in parts:
                        latency = result["latency"] = measure_latency(browser, url, args.seconds, Path(tmp))
                        ok = ok and (latency["latency_p50_ms"] <= TARGETS["latency_p50_ms"]
                                     and latency["latency_p99_ms"] <= TARGETS["latency_p99_ms"])
                    if "load" in parts:
                        load = result["load"] = measure_load(browser, url, args.nodes, args.rate,
                                                             args.seconds, Path(tmp))
                        ok = ok and load["max_frame_ms"] is not None \
                            and load["max_frame_ms"] <= TARGETS["max_frame_ms"]
            if "edit" in parts:
                edit = result["edit"] = measure_edit(browser, args.nodes, args.edits, Path(tmp))
                ok = ok and edit["edit_p50_ms"] <= TARGETS["edit_p50_ms"]
            if "first" in parts:
                first = result["first"] = measure_first(browser, args.first_samples, Path(tmp))
                ok = ok and first["first_diagram_p50_ms"] <= TARGETS["first_diagram_ms"] \
                    and first["progress_before_diagram"]
        finally:
            browser.close()
    print(json.dumps(result))
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
