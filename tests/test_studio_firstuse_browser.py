"""What a new user of umlbot studio hit on a laptop (issue 28 §5), read from the drawn page.

Debian's Chromium driven by Playwright at 1 280 x 720: the ⋔ mark of a node that calls an activity
beside (not over) its figures, the Calls panel's words whole, the component diagram whole, the
clock the figures are in. Screenshots under out/.
"""

from __future__ import annotations

import json
import re
import shutil
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from conftest import BrokerProcess
from playwright.sync_api import Browser, Page, expect
from robot_run import CAR_MODEL
from studio_support import chromium, shot, studio

WAIT_MS = 30_000


@pytest.fixture(scope="module")
def browser() -> Iterator[Browser]:
    with chromium() as launched:
        yield launched


def open_page(browser: Browser, url: str, errors: list[str], width: int = 1280, height: int = 720) -> Page:
    page = browser.new_page(viewport={"width": width, "height": height})
    page.on("pageerror", lambda exc: errors.append(str(exc)))
    page.goto(url)
    page.set_default_timeout(WAIT_MS)
    page.wait_for_function("window.__studio && window.__studio.ready === true")
    return page


def show(page: Page, diagram: str) -> None:
    page.locator(f'#diagram-list [data-diagram="{diagram}"]').click()
    expect(page.locator(f'svg[data-diagram="{diagram}"]')).to_be_visible()


def trace_line(node: str, kind: str, end: float, ms: float, **extra: Any) -> str:
    event = {"lane": "RaspberryPI", "node": node, "kind": kind, "start": end - ms / 1000, "end": end,
             "duration_ms": ms, "level": "info", "detail": node, **extra}
    return json.dumps(event) + "\n"


def write_trace(path: Path) -> Path:
    t0 = 1_800_000_000.0
    text = trace_line("start", "start", t0, 0.0)
    for i in range(1, 40):  # a lane call with long figures (39 runs, p50 and p99 of ~110 ms)
        text += trace_line("stop_step", "action", t0 + i, 100.0 + i * 0.5123, detail="Stop")
    # feature calls: their rows in the Calls panel (constant arguments, an expression, a value)
    text += trace_line("look_ahead", "action", t0 + 41, 0.091)
    text += trace_line("left_power", "action", t0 + 42, 170.25)
    text += trace_line("ping_ahead", "datastore", t0 + 43, 12.5, value=42)
    path.write_text(text, encoding="utf-8")
    return path


def boxes_overlap(a: dict[str, float], b: dict[str, float]) -> bool:
    return not (a["x"] + a["width"] <= b["x"] or b["x"] + b["width"] <= a["x"]
                or a["y"] + a["height"] <= b["y"] or b["y"] + b["height"] <= a["y"])


def test_the_call_mark_sits_beside_the_figures_and_the_calls_panel_keeps_words_whole(
        browser: Browser, tmp_path: Path) -> None:
    trace = write_trace(tmp_path / "run.jsonl")
    errors: list[str] = []
    with studio(["studio", str(CAR_MODEL), "--replay", str(trace), "--port", "0"], tmp_path) as proc:
        page = open_page(browser, proc.url, errors)
        show(page, "activity-main")
        page.locator("#replay-time").evaluate(
            "(el) => { el.value = el.max; el.dispatchEvent(new Event('input')); }")
        node = page.locator('g.node.calls[data-lane="RaspberryPI"][data-node="stop_step"]')
        expect(node).to_have_attribute("data-count", "39")
        node.scroll_into_view_if_needed()
        page.evaluate("""() => { const g = document.querySelector(
            'g.node.calls[data-lane="RaspberryPI"][data-node="stop_step"]');
            g.closest('g.lane')?.classList.remove('culled'); }""")
        stats = node.locator("text.stats")
        expect(stats).to_contain_text("p99")
        rake = page.evaluate("""() => {
          const g = document.querySelector('g.node.calls[data-lane="RaspberryPI"][data-node="stop_step"]');
          const r = g.querySelector('path.rake').getBBox(), s = g.querySelector('text.stats').getBBox();
          const box = g.querySelector('.shape').getBBox();
          return { rake: { x: r.x, y: r.y, width: r.width, height: r.height },
                   stats: { x: s.x, y: s.y, width: s.width, height: s.height },
                   node: { x: box.x, y: box.y, width: box.width, height: box.height } };
        }""")
        assert not boxes_overlap(rake["rake"], rake["stats"]), rake  # "p99 …" is not covered
        assert rake["stats"]["x"] >= rake["node"]["x"], rake  # and the figures stay in the node
        # the Calls panel at 1 280 px: each call on one line, a replay's text in words, latencies whole
        rows = page.locator("#calls tbody tr")
        expect(rows).to_have_count(3)
        shot(page, "studio-firstuse-calls-1280.png")
        cells = page.evaluate("""() => [...document.querySelectorAll('#calls tbody tr')].map((tr) =>
          [...tr.cells].map((td) => {
            const range = document.createRange();
            range.selectNodeContents(td);
            const lines = new Set([...range.getClientRects()].map((r) => Math.round(r.top)));
            return { cls: td.className.split(' ')[0], text: td.textContent, lines: lines.size,
                     whole: td.scrollWidth <= td.clientWidth + 1,
                     inside: td.getBoundingClientRect().right <= innerWidth + 0.5 };
          }))""")
        for row in cells:
            by = {c["cls"]: c for c in row}
            assert all(c["whole"] and c["inside"] for c in row), row
            assert by["latency"]["lines"] <= 1 and by["time"]["lines"] <= 1, row
            # a replay's call text wraps only between words, never inside one
            words = by["args"]["text"].split()
            assert by["args"]["lines"] <= len(words), row
        texts = {c["cls"]: c["text"] for row in cells for c in row}
        assert "LeftActuator.dutycycle(speed_percent)" in [c["text"] for row in cells for c in row], cells
        assert texts
        calls = [c for row in cells for c in row if c["cls"] == "call"]
        assert all(c["lines"] == 1 for c in calls), calls  # "Sensor.angle", "DistanceRead.value": one line
        expect(page.locator("#clock-note")).to_have_text("node times: the recorded run's clock")
        assert errors == [], errors
        page.close()


def test_the_component_diagram_opens_whole_on_a_laptop(browser: Browser, tmp_path: Path) -> None:
    errors: list[str] = []
    with studio(["studio", str(CAR_MODEL), "--port", "0"], tmp_path) as proc:
        page = open_page(browser, proc.url, errors)
        show(page, "components")
        canvas = page.locator("#canvas").bounding_box()
        assert canvas
        boxes = page.evaluate("""() => [...document.querySelectorAll(
            'svg[data-diagram="components"] g.component')].map((g) => {
              const r = g.getBoundingClientRect();
              return [g.dataset.component, r.left, r.right];
            })""")
        assert len(boxes) == 5, boxes
        for name, left, right in boxes:
            assert canvas["x"] <= left and right <= canvas["x"] + canvas["width"], (name, left, right, canvas)
        shot(page, "studio-firstuse-components-1280.png")
        # the five motion lanes do not fit a laptop's canvas readably: the edge says which go on
        show(page, "activity-motion")
        right = page.locator("#lanes-right")
        expect(right).to_be_visible()
        expect(right).to_contain_text("Stop")
        off = (right.get_attribute("data-lanes") or "").split(",")
        heads = page.evaluate("""() => [...document.querySelectorAll(
            'svg[data-diagram="activity-motion"] g.lane')]
            .filter((g) => !g.classList.contains('culled')).map((g) => g.dataset.lane)""")
        assert off and set(off) <= {"MoveForward", "MoveBackward", "TurnLeft", "TurnRight", "Stop"}, off
        shot(page, "studio-firstuse-motion-1280.png")
        for _ in range(len(off)):  # each click brings the next lane in; then none is left off
            right.click()
        expect(right).to_be_hidden()
        expect(page.locator("#lanes-left")).to_be_visible()
        lane = 'svg[data-diagram="activity-motion"] g.lane[data-lane="Stop"] .lane-bg'
        stop = page.locator(lane).bounding_box()
        assert stop and stop["x"] + stop["width"] <= canvas["x"] + canvas["width"] + 1, (stop, canvas)
        expect(page.locator("#follow")).to_have_attribute("aria-pressed", "false")  # moved by hand
        assert heads, heads
        assert errors == [], errors
        page.close()


def test_a_progress_indication_shows_until_the_first_diagram_is_drawn(
        browser: Browser, tmp_path: Path) -> None:
    errors: list[str] = []
    with studio(["studio", str(CAR_MODEL), "--port", "0"], tmp_path) as proc:
        page = browser.new_page(viewport={"width": 1280, "height": 720})
        page.on("pageerror", lambda exc: errors.append(str(exc)))
        page.set_default_timeout(WAIT_MS)
        held: list[Any] = []
        # the script is held back (a slow machine): the page says it is opening the model meanwhile
        page.route("**/static/studio.js", lambda route: held.append(route))
        page.goto(proc.url, wait_until="commit")
        progress = page.locator("#canvas-progress")
        expect(progress).to_be_visible()
        expect(progress).to_contain_text("Opening the model")
        expect(progress.locator(".spinner")).to_be_visible()
        page.wait_for_function("() => true")
        assert held, "the script was asked for"
        held[0].continue_()
        page.wait_for_function("window.__studio && window.__studio.ready === true")
        expect(progress).to_be_hidden()
        expect(page.locator('svg[data-diagram="activity-main"] g.node').first).to_be_visible()
        assert errors == [], errors
        page.close()


def test_a_yaml_syntax_error_shows_the_file_marked_and_its_text_is_fixed_in_the_page(
        browser: Browser, tmp_path: Path) -> None:
    folder = tmp_path / "car"
    shutil.copytree(CAR_MODEL, folder)
    measure = folder / "activities" / "measure.yaml"
    good = measure.read_text(encoding="utf-8")
    lines = good.splitlines(keepends=True)
    bad_line = next(i for i, line in enumerate(lines) if "{id:" in line) + 1
    lines[bad_line - 1] = lines[bad_line - 1].replace("}", "", 1)  # a mapping left open
    measure.write_text("".join(lines), encoding="utf-8")
    errors: list[str] = []
    with studio(["studio", str(folder), "--port", "0"], tmp_path) as proc:
        page = open_page(browser, proc.url, errors)
        entry = page.locator('#broken-files li[data-file="activities/measure.yaml"] button')
        expect(entry).to_be_visible()
        expect(entry).to_contain_text("cannot be read")
        entry.click()
        view = page.locator("#text-fix")
        expect(view).to_be_visible()
        expect(page.locator("#text-fix-title")).to_have_text("activities/measure.yaml")
        expect(page.locator("#text-fix-problem")).to_contain_text("line ")
        text = page.locator("#text-fix-text")
        assert text.input_value() == "".join(lines)
        # the marked line is the one the checker names, drawn over that line of the text
        line = int(view.get_attribute("data-line") or "0")
        assert line >= bad_line, (line, bad_line)
        mark = page.locator("#text-fix-mark").bounding_box()
        area = text.bounding_box()
        assert mark and area and area["y"] <= mark["y"] <= area["y"] + area["height"], (mark, area)
        # the caret is on that line
        caret_line = text.evaluate("(t) => t.value.slice(0, t.selectionStart).split('\\n').length")
        assert caret_line == line
        shot(page, "studio-firstuse-yaml-error.png")
        # fixed in the page: the file reads again, its diagram is back, the text view closes
        text.fill(good)
        page.locator("#text-fix-apply").click()
        expect(view).to_be_hidden()
        expect(page.locator("#broken-files li")).to_have_count(0)
        expect(page.locator('#diagram-list [data-diagram="activity-measure"]')).to_be_visible()
        page.locator("#save").click()
        expect(page.locator("#save")).to_have_attribute("data-dirty", "false")
        assert measure.read_text(encoding="utf-8") == good
        assert errors == [], errors
        page.close()


def test_a_motor_stopped_by_its_watchdog_is_marked_on_its_component_and_stays(
        browser: Browser, mosquitto_broker: BrokerProcess, raw_client: Any, tmp_path: Path) -> None:
    robot = "stopcar"  # a robot of its own: the broker keeps retained states between tests
    raw = raw_client(mosquitto_broker)
    topic = f"umlbot/{robot}/LeftActuator/state"
    errors: list[str] = []
    try:
        with studio(["studio", str(CAR_MODEL), "--port", "0", "--robot", robot], tmp_path,
                    mosquitto_broker.url) as proc:
            page = open_page(browser, proc.url, errors)
            show(page, "components")
            expect(page.locator("#broker-status")).to_have_text("broker connected")
            raw.publish(topic, json.dumps({"enabled": False, "clockwise": True, "dutycycle": 70,
                                           "running": False, "stop_reason": "watchdog"}), retain=True)
            left = page.locator('g.component[data-component="LeftActuator"]')
            expect(left).to_have_attribute("data-stop-reason", "watchdog")
            expect(left.locator("text.state tspan.stop")).to_have_text("⚠ safety stop: watchdog ")
            right = page.locator('g.component[data-component="RightActuator"]')
            expect(right).not_to_have_attribute("data-stop-reason", "watchdog")
            shot(page, "studio-firstuse-safety-stop.png")
            # a page opened later (after the run) still shows it: it is the motor's retained state
            again = open_page(browser, proc.url, errors)
            show(again, "components")
            expect(again.locator('g.component[data-component="LeftActuator"]')).to_have_attribute(
                "data-stop-reason", "watchdog")
            # running again clears it
            running = {"enabled": True, "running": True, "stop_reason": None}
            raw.publish(topic, json.dumps(running), retain=True)
            expect(left).not_to_have_attribute("data-stop-reason", "watchdog")
            assert errors == [], errors
            again.close()
            page.close()
    finally:
        raw.publish(topic, b"", retain=True)


def test_a_problem_is_said_in_a_modellers_words_with_its_line_one_click_away(
        browser: Browser, tmp_path: Path) -> None:
    folder = tmp_path / "car"
    shutil.copytree(CAR_MODEL, folder)
    motion = folder / "activities" / "motion.yaml"
    motion.write_text(motion.read_text(encoding="utf-8").replace("      - {id: end, kind: end}\n", "", 1),
                      encoding="utf-8")
    errors: list[str] = []
    with studio(["studio", str(folder), "--port", "0"], tmp_path) as proc:
        page = open_page(browser, proc.url, errors)
        problem = page.locator("#diagnostics li", has_text="needs an end")
        expect(problem.locator(".plain")).to_have_text("Swimlane MoveForward needs an end: add an end node.")
        # the checker's own message stays beside it, as `umlbot check` prints it
        expect(problem.locator(".text")).to_contain_text("error: swimlane 'MoveForward' has no end node")
        where = problem.locator("button.where")
        expect(where).to_have_text(re.compile(r"^activities/motion\.yaml:\d+$"))
        line = int((where.text_content() or "").rsplit(":", 1)[1])
        where.click()
        view = page.locator("#text-fix")
        expect(view).to_be_visible()
        expect(view).to_have_attribute("data-line", str(line))
        expect(page.locator("#text-fix-problem")).to_contain_text("needs an end")
        shot(page, "studio-firstuse-plain-words.png")
        page.keyboard.press("Escape")
        expect(view).to_be_hidden()
        assert errors == [], errors
        page.close()


def test_a_flow_is_drawn_by_dragging_from_a_nodes_output_port_to_another_node(
        browser: Browser, tmp_path: Path) -> None:
    folder = tmp_path / "car"
    shutil.copytree(CAR_MODEL, folder)
    errors: list[str] = []
    with studio(["studio", str(folder), "--port", "0"], tmp_path) as proc:
        page = open_page(browser, proc.url, errors, 1600, 1000)
        show(page, "activity-motion")
        lane = 'svg.diagram g.node[data-lane="MoveForward"]'
        source = page.locator(f'{lane}[data-node="left_forward"]')
        target = page.locator(f'{lane}[data-node="left_on"]')
        skipped = ('svg.diagram g.edge[data-lane="MoveForward"][data-source="left_forward"]'
                   '[data-target="{}"]')
        expect(page.locator(skipped.format("right_forward"))).to_have_count(1)
        source.hover()
        port = source.locator("circle.port-out").bounding_box()
        goal = target.bounding_box()
        assert port and goal
        actions = 0
        page.mouse.move(port["x"] + port["width"] / 2, port["y"] + port["height"] / 2)
        page.mouse.down()
        actions += 1
        page.mouse.move(goal["x"] + goal["width"] / 2, goal["y"] + goal["height"] / 2, steps=8)
        expect(target).to_have_class(re.compile(r"(^|\s)drop-target(\s|$)"))
        page.mouse.up()
        page.wait_for_function("window.__studio.edit.busy === false")
        # one drag made the flow: left_forward now leads to left_on (its `next`)
        expect(page.locator(skipped.format("left_on"))).to_have_count(1)
        expect(page.locator(skipped.format("right_forward"))).to_have_count(0)
        assert actions == 1
        page.locator("#save").click()
        expect(page.locator("#save")).to_have_attribute("data-dirty", "false")
        text = (folder / "activities" / "motion.yaml").read_text(encoding="utf-8")
        wired = "{id: left_forward, kind: action, call: LeftActuator.direction(true), next: left_on}"
        assert wired in text, text
        assert errors == [], errors
        page.close()


def test_a_palette_item_dropped_onto_a_flow_goes_between_and_enter_adds_after_the_selected(
        browser: Browser, tmp_path: Path) -> None:
    folder = tmp_path / "car"
    shutil.copytree(CAR_MODEL, folder)
    errors: list[str] = []
    with studio(["studio", str(folder), "--port", "0"], tmp_path) as proc:
        page = open_page(browser, proc.url, errors, 1600, 1000)
        show(page, "activity-motion")
        flow = 'svg.diagram g.edge[data-lane="MoveForward"][data-source="{}"][data-target="{}"]'
        hit = page.locator(flow.format("start", "left_forward") + " path.hit").bounding_box()
        item = page.locator('#palette .item[data-kind="action"]').bounding_box()
        assert hit and item
        page.mouse.move(item["x"] + item["width"] / 2, item["y"] + item["height"] / 2)
        page.mouse.down()
        page.mouse.move(hit["x"] + hit["width"] / 2, hit["y"] + hit["height"] / 2, steps=10)
        page.mouse.up()
        page.wait_for_function("window.__studio.edit.busy === false")
        # one drag: the new action sits between start and left_forward, wired both ways
        expect(page.locator(flow.format("start", "action1"))).to_have_count(1)
        expect(page.locator(flow.format("action1", "left_forward"))).to_have_count(1)
        expect(page.locator(flow.format("start", "left_forward"))).to_have_count(0)
        # by keyboard: a node selected, a palette item focused (its focus is seen), Enter
        page.locator('svg.diagram g.node[data-lane="MoveForward"][data-node="left_on"]').click()
        store = page.locator('#palette .item[data-kind="datastore"]')
        for _ in range(60):  # reached with Tab, as a keyboard user does (the nodes pass no selection)
            if store.evaluate("(e) => e === document.activeElement"):
                break
            page.keyboard.press("Tab")
        outline = store.evaluate("(e) => getComputedStyle(e).outlineStyle")
        assert outline != "none", outline
        page.keyboard.press("Enter")
        page.wait_for_function("window.__studio.edit.busy === false")
        expect(page.locator(flow.format("left_on", "datastore1"))).to_have_count(1)
        expect(page.locator(flow.format("datastore1", "right_on"))).to_have_count(1)
        assert errors == [], errors
        page.close()


def test_a_new_lane_starts_wired_and_a_selected_flow_goes_with_delete(
        browser: Browser, tmp_path: Path) -> None:
    folder = tmp_path / "car"
    shutil.copytree(CAR_MODEL, folder)
    errors: list[str] = []
    with studio(["studio", str(folder), "--port", "0"], tmp_path) as proc:
        page = open_page(browser, proc.url, errors, 1600, 1000)
        page.locator('#palette [name="lane-name"]').fill("Blink")
        page.locator('#palette [data-action="add-lane"]').click()
        page.wait_for_function("window.__studio.edit.busy === false")
        wired = page.locator('svg.diagram g.edge[data-lane="Blink"][data-source="start"][data-target="end"]')
        expect(wired).to_have_count(1, timeout=WAIT_MS)  # start -> end from the first moment (once drawn)
        # an action added after the start (selected), then its flow to the end selected and deleted
        page.locator('svg.diagram g.node[data-lane="Blink"][data-node="start"]').click()
        page.locator('#palette .item[data-kind="action"]').click()
        page.wait_for_function("window.__studio.edit.busy === false")
        flow = page.locator('svg.diagram g.edge[data-lane="Blink"][data-source="action1"][data-target="end"]')
        expect(flow).to_have_count(1, timeout=WAIT_MS)
        at = flow.locator("path.hit").evaluate("""(p) => {
          const m = p.getPointAtLength(p.getTotalLength() / 2), c = p.getScreenCTM();
          return [m.x * c.a + m.y * c.c + c.e, m.x * c.b + m.y * c.d + c.f]; }""")
        page.mouse.click(at[0], at[1])
        expect(flow).to_have_class(re.compile(r"(^|\s)selected(\s|$)"))
        page.keyboard.press("Delete")
        page.wait_for_function("window.__studio.edit.busy === false")
        expect(flow).to_have_count(0, timeout=WAIT_MS)
        assert errors == [], errors
        page.close()


def test_the_running_node_off_the_canvas_is_marked_on_its_edge(browser: Browser, tmp_path: Path) -> None:
    trace = write_trace(tmp_path / "run.jsonl")
    errors: list[str] = []
    with studio(["studio", str(CAR_MODEL), "--replay", str(trace), "--port", "0"], tmp_path) as proc:
        page = open_page(browser, proc.url, errors)
        show(page, "activity-main")
        slider = page.locator("#replay-time")

        def scrub(to: str) -> None:
            slider.evaluate(f"(el) => {{ el.value = {to}; el.dispatchEvent(new Event('input')); }}")

        scrub("el.max")
        marker = page.locator("#running-marker")
        expect(marker).to_be_hidden()  # followed: in view
        canvas = page.locator("#canvas").bounding_box()
        assert canvas
        # panned by hand far from it: Follow goes off, and the edge says where the robot is
        page.keyboard.press("l")
        x, y = canvas["x"] + 300, canvas["y"] + 60
        for _ in range(4):  # (within the window: the page gets every move)
            page.mouse.move(x, y)
            page.mouse.down()
            page.mouse.move(x + 20, y + 500, steps=5)
            page.mouse.up()
        expect(page.locator("#follow")).to_have_attribute("aria-pressed", "false")
        scrub("el.max - 0.5")
        scrub("el.max")
        active = page.locator('g.node.active[data-lane="RaspberryPI"]')
        expect(active).to_have_attribute("data-node", "ping_ahead")
        expect(marker).to_be_visible()
        expect(marker).to_have_text(re.compile(r"^[↑↓←→] running: ping_ahead$"))
        box = marker.bounding_box()
        assert box and canvas["y"] <= box["y"] <= canvas["y"] + canvas["height"], (box, canvas)
        shot(page, "studio-firstuse-running-marker.png")
        marker.click()  # follows again: the node is shown, the marker goes
        expect(page.locator("#follow")).to_have_attribute("aria-pressed", "true")
        expect(marker).to_be_hidden()
        assert errors == [], errors
        page.close()


#: the edge crossings of the reference car's `main` at its opening view (6 on 2026-11-28; 3 since its
#: branching sub-behaviours open collapsed, test_studio_regions_browser.py)
MAIN_CROSSINGS_MAX = 3


def test_crossings_and_label_problems_after_edits_equal_those_after_a_reload(
        browser: Browser, tmp_path: Path) -> None:
    folder = tmp_path / "car"
    shutil.copytree(CAR_MODEL, folder)
    errors: list[str] = []
    with studio(["studio", str(folder), "--port", "0"], tmp_path) as proc:
        page = open_page(browser, proc.url, errors, 1600, 1000)
        show(page, "activity-main")

        def quality() -> dict[str, int]:
            page.wait_for_function("window.__studio.quality('activity-main') !== null")
            result: dict[str, int] = page.evaluate("window.__studio.quality('activity-main')")
            return result

        # the big diagram: every region open (features/regions), more than 100 flows, as many
        # crossings as before regions; then its opening view again
        page.evaluate("window.__studio.regions('activity-main', 'open')")
        expect(page.locator('g.node[data-kind="region"]')).to_have_count(0, timeout=WAIT_MS)
        whole = quality()
        assert whole["flows"] > 100 and whole["crossings"] <= 6 and whole["labels"] == 0, whole
        page.evaluate("window.__studio.regions('activity-main', 'opening')")
        expect(page.locator('g.node[data-kind="region"]')).to_have_count(2, timeout=WAIT_MS)
        opened = quality()
        assert opened["flows"] > 75, opened  # what is drawn: the two boxes with their flows
        print("QUALITY activity-main at opening:", opened)
        # the opening view as drawn today (docs/performance.md): no more crossings, no guard problem;
        # issue 28's target, at most 3 crossings, is reached by drawing the two branching
        # sub-behaviours collapsed (ELK's options and a reroute of the flows had left 5 or more)
        assert opened["crossings"] <= MAIN_CROSSINGS_MAX and opened["labels"] == 0, opened
        # a scripted sequence of edits: a value changed twice
        for value in ("80", "75"):
            page.locator('svg.diagram g.node[data-lane="RaspberryPI"][data-node="set_speed"]').click()
            page.locator('#props input[name="value"]').fill(value)
            page.locator('#props input[name="value"]').press("Enter")
            page.wait_for_function("window.__studio.edit.busy === false")
        edited = quality()
        page.reload()
        page.wait_for_function("window.__studio && window.__studio.ready === true")
        show(page, "activity-main")
        assert quality() == edited == opened, (opened, edited)
        assert errors == [], errors
        page.close()


AXE = (Path(__file__).resolve().parent.parent / "umlbot" / "studio" / "web" / "node_modules" / "axe-core"
       / "axe.min.js")


def test_no_serious_or_critical_accessibility_violations(browser: Browser, tmp_path: Path) -> None:
    # axe-core (an npm devDependency of the page, installed by `make web`), injected by Playwright
    assert AXE.is_file(), "run `make web` (npm ci) first: axe-core is a devDependency of the page"
    folder = tmp_path / "car"
    shutil.copytree(CAR_MODEL, folder)
    errors: list[str] = []
    with studio(["studio", str(folder), "--port", "0"], tmp_path) as proc:
        page = open_page(browser, proc.url, errors)
        page.add_script_tag(path=str(AXE))
        found: list[str] = []
        for diagram in ("activity-main", "components"):
            show(page, diagram)
            result = page.evaluate("() => axe.run(document, {resultTypes: ['violations']})")
            found += [f"{diagram}: {v['impact']} {v['id']}: {v['help']} "
                      f"{[n['target'] for n in v['nodes'][:3]]}"
                      for v in result["violations"] if v["impact"] in ("serious", "critical")]
        assert found == [], "\n".join(found)
        assert errors == [], errors
        page.close()
