"""Collapsible regions of a big activity diagram (issue 28 §3), read from the drawn page.

Debian's Chromium driven by Playwright: the reference car's `main` opens with its two branching
sub-behaviours collapsed (3 crossings instead of 6, counted on what is drawn); a region opens by
the pointer, by Enter and by Space on its focused box; every region open draws `main` as before;
during a replayed run a node inside a collapsed region lights its box, with the box's count, and
Follow brings the box into view. Screenshots under out/.
"""

from __future__ import annotations

import json
import re
import shutil
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from playwright.sync_api import Browser, Page, expect
from robot_run import CAR_MODEL
from studio_support import chromium, shot, studio

WAIT_MS = 30_000
MAIN = "activity-main"
LANE = 'svg.diagram g.node[data-lane="RaspberryPI"]'
#: crossings of `main` at its opening view (docs/performance.md, issue 28), and expanded fully
OPENING_MAX = 3
EXPANDED = 6


@pytest.fixture(scope="module")
def browser() -> Iterator[Browser]:
    with chromium() as launched:
        yield launched


def open_main(browser: Browser, url: str, errors: list[str]) -> Page:
    page = browser.new_page(viewport={"width": 1600, "height": 1000})
    page.on("pageerror", lambda exc: errors.append(str(exc)))
    page.goto(f"{url}#diagram={MAIN}")
    page.set_default_timeout(WAIT_MS)
    page.wait_for_function("window.__studio && window.__studio.ready === true")
    expect(page.locator(f'svg[data-diagram="{MAIN}"]')).to_be_visible()
    return page


def quality(page: Page) -> dict[str, int]:
    page.wait_for_function(f"window.__studio.quality('{MAIN}') !== null")
    result: dict[str, int] = page.evaluate(f"window.__studio.quality('{MAIN}')")
    return result


def node(name: str) -> str:
    return f'{LANE}[data-node="{name}"]'


def test_regions_open_by_pointer_and_keyboard_and_the_opening_view_crosses_less(
        browser: Browser, tmp_path: Path) -> None:
    errors: list[str] = []
    with studio(["studio", str(CAR_MODEL), "--port", "0"], tmp_path) as proc:
        page = open_main(browser, proc.url, errors)
        opened = quality(page)
        print("QUALITY activity-main at opening (regions collapsed):", opened)
        assert opened["crossings"] <= OPENING_MAX and opened["labels"] == 0, opened
        boxes = page.locator(f'{LANE}[data-kind="region"]')
        expect(boxes).to_have_count(2)
        look = page.locator(node("region:forget_sides"))
        aside = page.locator(node("region:look_aside"))
        # labelled with what it holds; its nodes are not drawn, its flows in and out are
        expect(look.locator("text.label")).to_have_text(re.compile(r"^18 steps: aside = 'none' …$"))
        expect(aside.locator("text.label")).to_have_text(re.compile(r"^19 steps: Measure …$"))
        expect(look).to_have_attribute("aria-expanded", "false")
        expect(page.locator(node("pick_side"))).to_have_count(0)
        expect(page.locator('g.edge[data-lane="RaspberryPI"][data-target="region:forget_sides"]')).to_have_count(1)
        expect(page.locator('g.edge[data-lane="RaspberryPI"][data-source="region:look_aside"]')).to_have_count(4)
        # nodes the path through the loop shows stay drawn
        for name in ("set_speed", "running", "choose", "forward", "stop_step", "steer", "halt"):
            expect(page.locator(node(name))).to_have_count(1)
        page.evaluate("window.__studio.reveal('RaspberryPI', 'region:forget_sides')")
        shot(page, "studio-regions-collapsed.png")

        # the pointer: a click opens it, the view stays
        look.click()
        expect(page.locator(node("pick_side"))).to_have_count(1, timeout=WAIT_MS)
        expect(look).to_have_count(0)
        expect(aside).to_have_count(1)  # only that one
        one_open = quality(page)
        assert one_open["flows"] > opened["flows"], (opened, one_open)
        shot(page, "studio-regions-one-open.png")

        # the keyboard: the box is focusable, shows its focus, Enter opens it and the focus goes
        # to the region's first node
        aside.focus()
        outline = aside.locator("rect.shape").last.evaluate("(r) => getComputedStyle(r).strokeDasharray")
        assert outline not in ("", "none"), outline
        page.keyboard.press("Enter")
        expect(page.locator(node("into_opening"))).to_have_count(1, timeout=WAIT_MS)
        expect(boxes).to_have_count(0, timeout=WAIT_MS)
        page.wait_for_function(
            "document.activeElement && document.activeElement.getAttribute('data-node') === 'look_aside'")
        full = quality(page)
        print("QUALITY activity-main, every region open:", full)
        assert full["flows"] == 129 and full["crossings"] <= EXPANDED and full["labels"] == 0, full

        # back to the opening view; Space opens a box too
        page.evaluate(f"window.__studio.regions('{MAIN}', 'opening')")
        expect(boxes).to_have_count(2, timeout=WAIT_MS)
        assert quality(page) == opened
        look.focus()
        page.keyboard.press(" ")
        expect(page.locator(node("pick_side"))).to_have_count(1, timeout=WAIT_MS)
        expect(boxes).to_have_count(1, timeout=WAIT_MS)
        # every region open (the page's hook): `main` as drawn before regions
        page.evaluate(f"window.__studio.regions('{MAIN}', 'open')")
        expect(boxes).to_have_count(0, timeout=WAIT_MS)
        assert quality(page) == full
        # a diagnostic's reveal of a node inside a collapsed region opens it
        page.evaluate(f"window.__studio.regions('{MAIN}', 'opening')")
        expect(boxes).to_have_count(2, timeout=WAIT_MS)
        page.evaluate("window.__studio.reveal('RaspberryPI', 'enter_left')")
        expect(page.locator(node("enter_left"))).to_have_count(1, timeout=WAIT_MS)
        expect(aside).to_have_count(0)
        assert errors == [], errors
        page.close()


def trace_line(node_id: str, kind: str, end: float, ms: float, **extra: Any) -> str:
    event = {"lane": "RaspberryPI", "node": node_id, "kind": kind, "start": end - ms / 1000, "end": end,
             "duration_ms": ms, "level": "info", "detail": node_id, **extra}
    return json.dumps(event) + "\n"


def test_a_collapsed_region_lights_up_while_the_run_is_inside_and_follow_shows_it(
        browser: Browser, tmp_path: Path) -> None:
    t0 = 1_800_000_000.0
    text = trace_line("start", "start", t0, 0.0)
    text += trace_line("ping_ahead", "datastore", t0 + 1, 5.0, value=12)
    text += trace_line("running", "decision", t0 + 2, 0.1, value="choose")
    text += trace_line("choose", "decision", t0 + 3, 0.1, value="forget_sides")
    for i, name in enumerate(("forget_sides", "forget_left", "forget_right")):
        text += trace_line(name, "datastore", t0 + 4 + i, 0.2, value="none")
    text += trace_line("look", "action", t0 + 8, 300.0)
    trace = tmp_path / "run.jsonl"
    trace.write_text(text, encoding="utf-8")
    errors: list[str] = []
    with studio(["studio", str(CAR_MODEL), "--replay", str(trace), "--port", "0"], tmp_path) as proc:
        page = open_main(browser, proc.url, errors)
        box = page.locator(node("region:forget_sides"))
        expect(box).to_have_count(1)
        # far from the box first (its start), Follow on
        page.evaluate("window.__studio.reveal('RaspberryPI', 'set_speed')")
        page.locator("#follow").click()
        expect(page.locator("#follow")).to_have_attribute("aria-pressed", "true")
        page.locator("#replay-time").evaluate(
            "(el) => { el.value = el.max; el.dispatchEvent(new Event('input')); }")
        # `look` ran last: its region's box is the active node, counted by the times the run went in
        expect(box).to_have_class(re.compile(r"(^|\s)active(\s|$)"))
        expect(box).to_have_attribute("data-count", "1")
        expect(box.locator("text.stats")).to_have_text("\u00d71 in")
        expect(page.locator('g.node.active[data-lane="RaspberryPI"]')).to_have_count(1)
        # Follow shows it: the box comes into the canvas
        page.wait_for_function(
            """() => { const b = document.querySelector('g.node[data-node="region:forget_sides"]')
                                 .getBoundingClientRect();
                       const c = document.querySelector('#canvas').getBoundingClientRect();
                       return b.left >= c.left && b.right <= c.right
                           && b.top >= c.top && b.bottom <= c.bottom; }""")
        shot(page, "studio-regions-running.png")
        # opened, the node itself is the active one
        box.click()
        expect(page.locator(node("look"))).to_have_class(re.compile(r"(^|\s)active(\s|$)"), timeout=WAIT_MS)
        expect(page.locator(node("look"))).to_have_attribute("data-count", "1")
        assert errors == [], errors
        page.close()


def test_an_edit_inside_a_collapsed_region_opens_it(browser: Browser, tmp_path: Path) -> None:
    folder = tmp_path / "car"
    shutil.copytree(CAR_MODEL, folder)
    errors: list[str] = []
    with studio(["studio", str(folder), "--port", "0"], tmp_path) as proc:
        page = open_main(browser, proc.url, errors)
        box = page.locator(node("region:forget_sides"))
        expect(box).to_have_count(1)
        # an edit while it is open: the no-room look forgets the opening beside the way
        page.evaluate("window.__studio.reveal('RaspberryPI', 'region:forget_sides')")
        box.click()
        store = page.locator(node("forget_sides"))
        expect(store).to_have_count(1, timeout=WAIT_MS)
        page.evaluate("window.__studio.reveal('RaspberryPI', 'forget_sides')")
        store.click()
        page.locator('#props input[name="value"]').fill("'left'")
        page.locator('#props input[name="value"]').press("Enter")
        page.wait_for_function("window.__studio.edit.busy === false")
        # back to the opening view: the region is a box again
        page.evaluate(f"window.__studio.regions('{MAIN}', 'opening')")
        expect(box).to_have_count(1, timeout=WAIT_MS)
        expect(store).to_have_count(0)
        # undone: the edit changes a node inside the box, so the box opens and the node is drawn
        page.locator("#undo").click()
        page.wait_for_function("window.__studio.edit.busy === false")
        expect(store).to_have_count(1, timeout=WAIT_MS)
        expect(box).to_have_count(0)
        expect(page.locator(node("region:look_aside"))).to_have_count(1)  # the other stays shut
        assert errors == [], errors
        page.close()
