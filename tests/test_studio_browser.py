"""umlbot studio in a real browser (Debian's Chromium driven by Playwright).

A real broker, the car's services (mock drivers) and a real `umlbot run` drive the page; the tests
read what a person sees from the DOM/SVG and keep screenshots under out/ (look at them).
"""

from __future__ import annotations

import json
import math
import random
import re
import socket
import statistics
import subprocess
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from conftest import BrokerProcess
from playwright.sync_api import Browser, Page, expect
from robot_run import CAR_MODEL, Proc, compile_car, processes, start_services, umlbot_argv
from studio_support import BROKEN_MODEL, StudioProc, chromium, shot, studio

REPO = Path(__file__).resolve().parent.parent
ROBOT = "car"
WAIT_MS = 30_000


@pytest.fixture(scope="module")
def browser() -> Iterator[Browser]:
    with chromium() as launched:
        yield launched


def open_page(browser: Browser, url: str) -> Page:
    page = browser.new_page(viewport={"width": 1600, "height": 1000})
    errors: list[str] = []
    page.on("pageerror", lambda exc: errors.append(str(exc)))
    # a studio without --fleet has no fleet view: the page does not ask for it (no 404 logged)
    page.on("request", lambda request: errors.append(request.url) if "/api/fleet" in request.url else None)
    page.on("response", lambda response: errors.append(f"{response.status} {response.url}")
            if response.status == 404 else None)
    page.goto(url)
    page.wait_for_function("window.__studio && window.__studio.ready === true", timeout=WAIT_MS)
    page.set_default_timeout(WAIT_MS)
    page.wait_for_timeout(300)
    assert errors == [], errors
    return page


def show(page: Page, diagram: str) -> None:
    page.locator(f'#diagram-list [data-diagram="{diagram}"]').click()
    expect(page.locator(f'svg[data-diagram="{diagram}"]')).to_be_visible()


def test_a_live_run_is_highlighted_with_counts_timings_calls_and_availability(
    browser: Browser, mosquitto_broker: BrokerProcess, tmp_path: Path
) -> None:
    compiled = compile_car(tmp_path)
    with processes() as made, studio(["studio", str(CAR_MODEL), "--port", "0", "--robot", ROBOT], tmp_path,
                                     mosquitto_broker.url) as proc:
        services = start_services(made, tmp_path, lambda kind: mosquitto_broker.url, robot=ROBOT)
        page = open_page(browser, proc.url)
        show(page, "components")
        for name in ("LeftActuator", "RightActuator", "Sensor", "DistanceRead", "RaspberryPI"):
            # the services' start (a few seconds each under load), not expect's default 5 s
            expect(page.locator(f'g.component[data-component="{name}"]')).to_have_attribute(
                "data-state", "online", timeout=WAIT_MS)
            # the deployment says `auto`; the services run --driver mock, and their status says so
            expect(page.locator(f'g.component[data-component="{name}"]')).to_have_attribute(
                "data-driver", "mock")
        expect(page.locator('g.component[data-component="LeftActuator"] text.impl')).to_have_text(
            "l298n · motor · auto → mock")
        made.append(Proc("run", umlbot_argv("run", str(compiled), "--robot", ROBOT), tmp_path,
                         mosquitto_broker.url))
        expect(page.locator("#orchestrator-status")).to_have_attribute("data-state", "running",
                                                                       timeout=WAIT_MS)

        show(page, "activity-main")
        # the main lane's current node is highlighted, and nodes it ran show counts and timings
        expect(page.locator('g.node.active[data-lane="RaspberryPI"]')).to_have_count(1)
        # (a step forward is taken once a loop: an action calling the MoveForward lane, with its
        # timings; the mock sonar's 100 cm ahead keeps the car going straight)
        selector = 'g.node[data-lane="RaspberryPI"][data-node="forward"]'
        step = page.locator(selector)
        page.wait_for_function(
            "s => Number(document.querySelector(s)?.getAttribute('data-count') || 0) >= 2", arg=selector)
        assert float(step.get_attribute("data-p50-ms") or "nan") > 0
        expect(step.locator("text.stats")).to_contain_text("ms")
        # the tuning datastore shows its value; the decision shows which branch it took
        speed = page.locator('g.node[data-lane="RaspberryPI"][data-node="set_speed"]')
        expect(speed.locator("text.value")).to_have_text("70")
        taken = page.locator('g.edge[data-lane="RaspberryPI"][data-source="running"]'
                             '[data-target="choose"]')
        expect(taken).not_to_have_attribute("data-count", "0")
        # calls, with boolean arguments shown as they are
        enabled = page.locator('#calls tbody tr[data-component="LeftActuator"][data-feature="enabled"]')
        expect(enabled.first).to_be_visible()
        args_seen = set(enabled.locator("td.args").all_text_contents())
        assert args_seen and args_seen <= {"[true]", "[false]"}, args_seen
        # each trace event's arrival at the page is timed too (bench/studio.py's socket figures):
        # from the node's end, never before it, and before the frame that drew it
        arrivals, drawn = page.evaluate(
            "[window.__studio.arrivals.slice(), window.__studio.latencies.slice()]")
        assert arrivals and drawn
        assert all(-2 < ms < 60_000 for ms in arrivals), arrivals[:20]
        assert statistics.median(arrivals) <= statistics.median(drawn), (arrivals[:20], drawn[:20])
        page.evaluate("window.__studio.reveal('RaspberryPI', 'forward')")  # the loop, not the set-up
        page.wait_for_timeout(1500)  # a few loops more, then the picture of docs/studio.md
        shot(page, "studio-live.png")

        # a component going offline turns red; the orchestrator fails safe and says why
        motor = next(s for s in services if s.name == "motor")
        assert motor.stop() == 0
        show(page, "components")
        left = page.locator('g.component[data-component="LeftActuator"]')
        expect(left).to_have_attribute("data-state", "offline")
        expect(left).to_have_class(_has("offline"))
        expect(left).not_to_have_attribute("data-driver", "mock")  # nothing runs it now
        expect(left.locator("text.impl")).to_have_text("l298n · motor · auto")
        expect(page.locator("#orchestrator-status")).to_have_attribute("data-state", "failed")
        expect(page.locator("#orchestrator-status")).to_contain_text("LeftActuator")
        shot(page, "studio-offline.png")
        page.close()


#: JS: the box of what `selector` finds lies inside the canvas (the part of the page the diagram shows)
INSIDE_CANVAS = """selector => {
    const el = document.querySelector(selector);
    if (!el) return false;
    const c = document.querySelector('#canvas').getBoundingClientRect();
    const b = el.getBoundingClientRect();
    return b.width > 0 && b.left >= c.left && b.right <= c.right && b.top >= c.top && b.bottom <= c.bottom;
}"""


def _viewport(page: Page) -> str:
    return page.locator('svg[data-diagram="activity-main"] g.viewport').get_attribute("transform") or ""


def _pan_by_hand(page: Page, dx: float, dy: float) -> None:
    """Drag the diagram by (dx, dy) from a point of the canvas where no node is (a pan), on the
    side the drag leaves from (a drag to the left starts on the right)."""
    start = page.evaluate("""leftwards => {
        const c = document.querySelector('#canvas').getBoundingClientRect();
        for (let y = c.top + 60; y < c.bottom - 60; y += 20)
            for (let i = 20; i < c.width - 20; i += 20) {
                const x = leftwards ? c.right - i : c.left + i;
                const hit = document.elementFromPoint(x, y);
                if (hit && (hit.matches('svg.diagram') || hit.matches('.lane-bg'))) return [x, y];
            }
        return null;
    }""", dx < 0)
    assert start is not None, "no empty place on the canvas to drag from"
    page.mouse.move(start[0], start[1])
    page.mouse.down()
    page.mouse.move(start[0] + dx, start[1] + dy, steps=6)
    page.mouse.up()


def test_the_view_follows_the_running_robot_until_panned_by_hand(
    browser: Browser, mosquitto_broker: BrokerProcess, tmp_path: Path
) -> None:
    """The car's main opens at its start (the start-up datastores); the loop the robot runs is
    further down. Follow (on by default) pans the view to the node that ran last, the lane keeps
    its name on screen, a pan by hand turns following off (the view stays put), `l` turns it on."""
    compiled = compile_car(tmp_path)
    with processes() as made, studio(["studio", str(CAR_MODEL), "--port", "0", "--robot", ROBOT], tmp_path,
                                     mosquitto_broker.url) as proc:
        start_services(made, tmp_path, lambda kind: mosquitto_broker.url, robot=ROBOT)
        page = open_page(browser, proc.url + "#diagram=activity-main")
        follow = page.locator("#follow")
        expect(follow).to_have_attribute("aria-pressed", "true")
        opening = _viewport(page)
        made.append(Proc("run", umlbot_argv("run", str(compiled), "--robot", ROBOT), tmp_path,
                         mosquitto_broker.url))
        expect(page.locator("#orchestrator-status")).to_have_attribute("data-state", "running")
        active = 'svg[data-diagram="activity-main"] g.node.active[data-lane="RaspberryPI"]'
        page.wait_for_function("() => window.__studio.followPans > 0")
        page.wait_for_function(INSIDE_CANVAS, arg=active)
        assert _viewport(page) != opening  # it panned to get there (never zoomed: the same scale)
        assert _viewport(page).split("scale")[1] == opening.split("scale")[1]
        # the lane's name stays on screen although its header is far above
        title = 'svg[data-diagram="activity-main"] g.lane[data-lane="RaspberryPI"] .lane-title'
        page.wait_for_function(INSIDE_CANVAS, arg=title)
        page.wait_for_timeout(2500)  # into the loop the robot runs: the picture of docs/studio.md
        page.wait_for_function(INSIDE_CANVAS, arg=active)
        shot(page, "studio-follow.png")

        _pan_by_hand(page, -700, 0)  # the lane (the diagram's only one) goes off to the left
        expect(follow).to_have_attribute("aria-pressed", "false")
        assert not page.evaluate(INSIDE_CANVAS, active)
        pans, where = page.evaluate("window.__studio.followPans"), _viewport(page)
        applied = page.evaluate("window.__studio.applied")
        page.wait_for_timeout(1500)  # the robot runs on; the view stays where the user put it
        assert page.evaluate("window.__studio.applied") > applied
        assert (page.evaluate("window.__studio.followPans"), _viewport(page)) == (pans, where)

        page.keyboard.press("l")  # follow again
        expect(follow).to_have_attribute("aria-pressed", "true")
        page.wait_for_function("p => window.__studio.followPans > p", arg=pans)
        page.wait_for_function(INSIDE_CANVAS, arg=active)
        page.close()


def _has(css_class: str) -> re.Pattern[str]:
    return re.compile(rf"(^|\s){re.escape(css_class)}(\s|$)")


def _trace_line(node: str, kind: str, end: float, **extra: Any) -> str:
    event = {"lane": "RaspberryPI", "node": node, "kind": kind, "start": end - 0.01, "end": end,
             "duration_ms": 10.0, "level": "info", "detail": node, **extra}
    return json.dumps(event) + "\n"


def test_a_replay_scrubbed_to_a_moment_shows_that_moments_node_and_values(
    browser: Browser, tmp_path: Path
) -> None:
    trace = tmp_path / "run.jsonl"
    t0 = 1_800_000_000.0
    trace.write_text(
        _trace_line("start", "start", t0 + 0.0)
        + _trace_line("set_speed", "datastore", t0 + 1.0, value=70)
        + _trace_line("set_forward", "datastore", t0 + 2.0, value=300)
        + _trace_line("set_speed", "datastore", t0 + 3.0, value=55)
        + _trace_line("stop_all", "action", t0 + 4.0, error="Stop failed: time-out", level="error"),
        encoding="utf-8")
    with studio(["studio", str(CAR_MODEL), "--replay", str(trace), "--port", "0"], tmp_path) as proc:
        page = open_page(browser, proc.url)
        show(page, "activity-main")
        expect(page.locator("#replay")).to_be_visible()
        slider = page.locator("#replay-time")

        def scrub(seconds: float) -> None:
            slider.evaluate("(el, v) => { el.value = String(v); el.dispatchEvent(new Event('input')); }",
                            seconds)

        active = page.locator('g.node.active[data-lane="RaspberryPI"]')
        speed = page.locator('g.node[data-lane="RaspberryPI"][data-node="set_speed"]')
        scrub(2.5)
        expect(active).to_have_attribute("data-node", "set_forward")
        expect(speed.locator("text.value")).to_have_text("70")
        expect(speed).to_have_attribute("data-count", "1")
        scrub(3.5)
        expect(active).to_have_attribute("data-node", "set_speed")
        expect(speed.locator("text.value")).to_have_text("55")
        expect(speed).to_have_attribute("data-count", "2")
        shot(page, "studio-replay.png")
        scrub(4.5)
        failed = page.locator('g.node[data-lane="RaspberryPI"][data-node="stop_all"]')
        expect(failed).to_have_class(_has("error"))
        expect(failed).to_have_attribute("data-message", _has_text("time-out"))
        scrub(1.5)  # back in time: the later values and the error are gone
        expect(active).to_have_attribute("data-node", "set_speed")
        expect(speed.locator("text.value")).to_have_text("70")
        expect(failed).not_to_have_class(_has("error"))
        page.close()


def test_a_replay_fills_the_calls_panel_says_how_the_run_ended_and_shows_its_notes(
    browser: Browser, tmp_path: Path
) -> None:
    trace = tmp_path / "run.jsonl"
    t0 = 1_800_000_000.0

    def line(lane: str, node: str, kind: str, end: float, **extra: Any) -> str:
        event = {"lane": lane, "node": node, "kind": kind, "start": end - 0.005, "end": end,
                 "duration_ms": 5.0, "level": "error" if "error" in extra else "info", **extra}
        return json.dumps(event) + "\n"

    text = (line("Glance", "look_left", "action", t0 + 1.0, detail="Sensor.angle(135)")
            + line("Glance", "left", "datastore", t0 + 2.0, value=42, detail="left = DistanceRead.value()")
            + line("Ghost", "look_up", "action", t0 + 2.5, detail="Neck.tilt(10)")
            + line("Glance", "right", "datastore", t0 + 4.0, detail="right = DistanceRead.value()",
                   error="CallTimeout: no reply from DistanceRead.value within 2 s"))
    trace.write_text(text + text[:30], encoding="utf-8")  # the last line is cut off
    with studio(["studio", str(CAR_MODEL), "--replay", str(trace), "--port", "0"], tmp_path) as proc:
        page = open_page(browser, proc.url)
        notes = page.locator("#replay-notes")
        expect(notes).to_be_visible()
        expect(notes).to_contain_text("the last line is cut off")
        expect(notes).to_contain_text("1 event names a node not in the model (e.g. Ghost/look_up)")
        slider = page.locator("#replay-time")

        def scrub(seconds: float) -> None:
            slider.evaluate("(el, v) => { el.value = String(v); el.dispatchEvent(new Event('input')); }",
                            seconds)

        rows = page.locator("#calls tbody tr")
        orchestrator = page.locator("#orchestrator-status")
        scrub(1.5)  # (the trace starts at the first node's end, t0 + 1)
        expect(rows).to_have_count(2)
        newest = rows.nth(0)
        expect(newest).to_have_attribute("data-feature", "value")
        expect(newest.locator("td.args")).to_have_text("[]")
        expect(newest.locator("td.result")).to_have_text("42")
        expect(newest.locator("td.latency")).to_contain_text("5")
        expect(rows.nth(1).locator("td.args")).to_have_text("[135]")
        expect(orchestrator).to_have_attribute("data-state", "running")
        expect(orchestrator).to_contain_text("from the trace")
        scrub(3.0)  # the end: the failed call on top, the toolbar says how the run ended
        expect(rows).to_have_count(3)
        expect(rows.nth(0).locator("td.result")).to_have_text(
            "error: CallTimeout: no reply from DistanceRead.value within 2 s")
        expect(orchestrator).to_have_attribute("data-state", "failed")
        expect(orchestrator).to_contain_text("Glance/right: CallTimeout")
        shot(page, "studio-replay-end.png")
        scrub(0.5)  # back in time: the later calls are gone
        expect(rows).to_have_count(1)
        page.close()


def test_the_page_says_when_the_broker_is_not_reached(browser: Browser, tmp_path: Path) -> None:
    with socket.socket() as probe:  # a port nobody listens on
        probe.bind(("127.0.0.1", 0))
        port = probe.getsockname()[1]
    with studio(["studio", str(CAR_MODEL), "--port", "0", "--broker", f"mqtt://127.0.0.1:{port}"],
                tmp_path) as proc:
        page = open_page(browser, proc.url)
        broker = page.locator("#broker-status")
        expect(broker).to_be_visible()
        expect(broker).to_have_attribute("data-state", "failed")
        expect(broker).to_contain_text(f"broker mqtt://127.0.0.1:{port}: Connection refused, retrying")
        expect(broker).to_contain_text("(attempt ")  # it keeps trying
        shot(page, "studio-no-broker.png")
        page.close()


def test_a_timed_out_call_is_listed_where_it_was_made(
    browser: Browser, mosquitto_broker: BrokerProcess, raw_client: Any, tmp_path: Path
) -> None:
    raw = raw_client(mosquitto_broker)
    base = f"umlbot/{ROBOT}"
    with studio(["studio", str(CAR_MODEL), "--port", "0", "--robot", ROBOT], tmp_path,
                mosquitto_broker.url) as proc:
        page = open_page(browser, proc.url)
        expect(page.locator("#broker-status")).to_have_text("broker connected")
        raw.publish(f"{base}/DistanceRead/call/value",
                    json.dumps({"id": "q1", "reply_to": f"{base}/_reply/t"}))
        page.wait_for_timeout(300)
        raw.publish(f"{base}/Sensor/call/angle", json.dumps({"id": "q2", "reply_to": f"{base}/_reply/t",
                                                            "args": [45]}))
        raw.publish(f"{base}/_reply/t", '{"id":"q2","ok":true,"value":null}')
        rows = page.locator("#calls tbody tr")
        expect(rows).to_have_count(1)
        # the model's call_timeout_s is 2 s; the unanswered call is listed below the later one
        expect(rows).to_have_count(2, timeout=6_000)
        expect(rows.nth(0)).to_have_attribute("data-feature", "angle")
        expect(rows.nth(1)).to_have_attribute("data-feature", "value")
        expect(rows.nth(1).locator("td.result")).to_have_text("error: no reply within 2 s")
        expect(rows.nth(1).locator("td.latency")).to_have_text("")
        page.close()


def _nearest_rank(samples: list[float], q: float) -> float:
    ordered = sorted(samples)
    return ordered[min(len(ordered), max(1, math.ceil(q * len(ordered)))) - 1]


def test_p50_p99_of_many_samples_are_within_one_percent_in_bounded_memory(
    browser: Browser, tmp_path: Path
) -> None:
    """20 000 runs of one node, replayed: the page's p50/p99 (a log-bucket histogram per node,
    docs/studio.md) are within 1 % of the exact nearest-rank values at the end and at a scrubbed
    moment, and the histogram holds as many counters after 20 000 samples as after 10 000."""
    count = 20_000
    rng = random.Random(20_000)
    # lognormal around 8 ms, with a 2 % tail about ten times slower, at the trace's 1 µs resolution;
    # the first two runs span the whole range, so no later sample needs a new bucket
    def one_run() -> float:
        ms = rng.lognormvariate(math.log(8.0), 0.4) * (10 if rng.random() < 0.02 else 1)
        return round(min(200.0, max(1.0, ms)), 3)

    durations = [1.0, 200.0] + [one_run() for _ in range(count - 2)]
    t0 = 1_800_000_000.0
    trace = tmp_path / "many.jsonl"
    trace.write_text("".join(_trace_line("look_ahead", "action", t0 + i * 0.01, duration_ms=ms)
                             for i, ms in enumerate(durations)), encoding="utf-8")
    with studio(["studio", str(CAR_MODEL), "--replay", str(trace), "--port", "0"], tmp_path) as proc:
        page = open_page(browser, proc.url)
        show(page, "activity-main")
        node = page.locator('g.node[data-lane="RaspberryPI"][data-node="look_ahead"]')
        slider = page.locator("#replay-time")

        def at(runs: int) -> tuple[float, float, int]:
            """Scrub to just after the `runs`-th run: the shown p50, p99 and the page's counters."""
            slider.evaluate("(el, v) => { el.value = String(v); el.dispatchEvent(new Event('input')); }",
                            f"{(runs - 1) * 0.01 + 0.005:.3f}")
            expect(node).to_have_attribute("data-count", str(runs))
            counters = int(page.evaluate("window.__studio.durationCounters()"))
            return (float(node.get_attribute("data-p50-ms") or "nan"),
                    float(node.get_attribute("data-p99-ms") or "nan"), counters)

        half, half_counters = count // 2, 0
        for runs in (half, count, half):  # back in time too: the snapshot's values, not the end's
            p50, p99, counters = at(runs)
            for shown, q in ((p50, 0.5), (p99, 0.99)):
                exact = _nearest_rank(durations[:runs], q)
                # 1 % (the histogram) + 0.5 µs (the attribute is rounded to the microsecond)
                assert abs(shown - exact) <= 0.01 * exact + 0.0005, (runs, q, shown, exact)
            assert 0 < counters < 300, counters  # one node's histogram: ~1.2 % of its samples' count
            half_counters = half_counters or counters
            assert counters == half_counters, (runs, counters, half_counters)
        page.close()


def _has_text(text: str) -> re.Pattern[str]:
    return re.compile(re.escape(text))


def test_the_page_lists_the_checkers_messages_for_a_broken_model(browser: Browser, tmp_path: Path) -> None:
    model = tmp_path / "bad.yaml"
    model.write_text(BROKEN_MODEL, encoding="utf-8")
    check = subprocess.run(umlbot_argv("check", str(model)), capture_output=True, text=True, timeout=60,
                           check=False, cwd=tmp_path)
    printed = [line for line in check.stdout.splitlines() + check.stderr.splitlines() if ": error: " in line]
    assert printed
    with studio(["studio", str(model), "--port", "0"], tmp_path) as proc:
        page = open_page(browser, proc.url)
        expect(page.locator("#diagnostics li")).to_have_count(len(printed))
        shown = page.locator("#diagnostics li").all_text_contents()
        for line in printed:
            assert any(line in text for text in shown), (line, shown)
        shot(page, "studio-diagnostics.png")
        page.close()


def test_sim_studio_draws_the_track_the_car_and_its_pings(browser: Browser, tmp_path: Path) -> None:
    # a long track in real time (about 55 s to its goal): the car still drives when a page on a
    # loaded machine has opened (on the corridor at twice the speed the run could end first)
    track = REPO / "models" / "tracks" / "room_exit.yaml"
    proc = StudioProc(["sim", str(CAR_MODEL), "--track", str(track), "--port", "0", "--speed", "1",
                       "--timeout", "120", "--studio", "--studio-port", "0"], tmp_path)
    try:
        page = open_page(browser, proc.url)
        expect(page.locator("#sim svg")).to_be_visible()
        assert page.locator("#sim .wall").count() >= 1
        expect(page.locator("#sim .car")).to_have_count(1)
        page.wait_for_function("document.querySelectorAll('#sim .ping').length > 0")
        start = page.locator("#sim .car").get_attribute("transform")
        page.wait_for_function(
            "t => document.querySelector('#sim .car').getAttribute('transform') !== t", arg=start)
        show(page, "activity-main")
        expect(page.locator('g.node.active[data-lane="RaspberryPI"]')).to_have_count(1)
        page.evaluate("window.__studio.reveal('RaspberryPI', 'forward')")  # the loop, not the set-up
        page.wait_for_timeout(3000)  # the car drives on a little: the picture of docs/studio.md
        shot(page, "studio-sim.png")
        page.close()
    finally:
        proc.stop()


def test_a_page_opened_after_a_sim_run_draws_where_the_run_ended(browser: Browser, tmp_path: Path) -> None:
    proc = StudioProc(["sim", str(CAR_MODEL), "--port", "0", "--speed", "10", "--studio",
                       "--studio-port", "0"], tmp_path)
    try:
        proc.wait_line("the run has ended")
        page = open_page(browser, proc.url)
        expect(page.locator("#sim .sim-info")).to_contain_text("goal reached")
        expect(page.locator("#sim .sim-info")).to_contain_text("no collisions")
        start = page.locator("#sim .start")
        x0, y0 = float(start.get_attribute("cx") or "nan"), float(start.get_attribute("cy") or "nan")
        car = page.locator("#sim .car").get_attribute("transform") or ""
        where = re.match(r"translate\(([-\d.e]+),([-\d.e]+)\)", car)
        assert where is not None
        assert math.hypot(float(where[1]) - x0, float(where[2]) - y0) > 0.5
        assert page.locator("#sim .ping").count() > 0
        # the figures say their clock: the nodes' simulated time (0 ms for a call), the calls' wall clock
        expect(page.locator("#clock-note")).to_have_text("node times: simulated time · calls: wall clock")
        clock = page.locator("#clock-note")
        expect(clock).to_have_attribute("title", re.compile(r"takes none of it \(0 ms\)"))
        # a good run's broker closed with the run: the toolbar says the run ended, not red "lost"
        pill = page.locator("#broker-status")
        expect(pill).to_have_attribute("data-state", "ended")
        expect(pill).to_have_text("broker: the run has ended")
        page.wait_for_timeout(1500)  # and stays so (nothing is retried)
        expect(pill).to_have_attribute("data-state", "ended")
        page.close()
    finally:
        proc.stop()
