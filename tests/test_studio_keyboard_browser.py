"""umlbot studio by keyboard alone, in a real browser (Debian's Chromium driven by Playwright).

From an empty folder (`umlbot studio --new`), every step of a small edit is done with key presses
only — no click, no `focus()` from the test: Tab is pressed until the element wanted has the focus.
The starter model is created, the diagram switched, an action and a decision are added after the
selected node from the palette, a call is typed, the decision is connected back to the action and
its guard typed, a node is renamed, one deleted, the delete undone and redone, a swimlane added,
the view zoomed and panned, Follow toggled, and the model saved: the drawing (DOM) and the saved
files say each step happened. The focus is visible (a blue ring) on the diagram's nodes.
Screenshot under out/.
"""

from __future__ import annotations

import re
from collections.abc import Iterator
from pathlib import Path

import pytest
from playwright.sync_api import Browser, Page, expect
from studio_support import chromium, shot, studio

WAIT_MS = 30_000
MAX_TABS = 250


@pytest.fixture(scope="module")
def browser() -> Iterator[Browser]:
    with chromium() as launched:
        yield launched


def settled(page: Page) -> None:
    page.wait_for_function("window.__studio.edit.busy === false")
    page.wait_for_function("window.__studio.ready === true")


def has_focus(page: Page, selector: str) -> bool:
    return bool(page.evaluate(
        "(s) => { const a = document.activeElement; return !!a && a.matches(s); }", selector))


def tab_to(page: Page, selector: str, back: bool = False) -> int:
    """Press Tab (Shift-Tab when `back`) until the element matching `selector` has the focus; the
    number of presses. Fails when it is not reached: it is not reachable by keyboard."""
    for presses in range(MAX_TABS + 1):
        if has_focus(page, selector):
            return presses
        page.keyboard.press("Shift+Tab" if back else "Tab")
    raise AssertionError(f"{selector} not reached with {MAX_TABS} Tab presses")


def edge(lane: str, source: str, target: str) -> str:
    return f'svg.diagram g.edge[data-lane="{lane}"][data-source="{source}"][data-target="{target}"]'


def node(lane: str, node_id: str) -> str:
    return f'svg.diagram g.node[data-lane="{lane}"][data-node="{node_id}"]'


def scale(transform: str) -> float:
    m = re.search(r"scale\(([-\d.e]+)\)", transform)
    assert m, transform
    return float(m.group(1))


def viewport(page: Page) -> str:
    return str(page.locator('svg[data-diagram="activity-main"] g.viewport').get_attribute("transform"))


def test_a_small_edit_by_keyboard_only(browser: Browser, tmp_path: Path) -> None:
    folder = tmp_path / "kb_robot"
    errors: list[str] = []
    with studio(["studio", "--new", str(folder), "--port", "0"], tmp_path) as proc:
        page = browser.new_page(viewport={"width": 1600, "height": 1000})
        page.on("pageerror", lambda exc: errors.append(str(exc)))
        page.set_default_timeout(WAIT_MS)
        page.goto(proc.url)
        page.wait_for_function("window.__studio && window.__studio.ready === true && !!window.__studio.edit")

        # the starter model: Tab to "Create the model", Enter (the robot's name is proposed)
        tab_to(page, "#new-model")
        page.keyboard.press("Enter")
        expect(page.locator('#diagram-list [data-diagram="activity-main"]')).to_be_visible()
        settled(page)
        assert (folder / "model.yaml").is_file()
        lane = "RaspberryPI"
        of_kind = 'svg.diagram g.node[data-lane="{}"][data-kind="{}"]'
        start = str(page.locator(of_kind.format(lane, "start")).get_attribute("data-node"))
        end = str(page.locator(of_kind.format(lane, "end")).get_attribute("data-node"))

        # switching diagrams: the list's entries take Enter
        tab_to(page, '#diagram-list [data-diagram="components"]')
        page.keyboard.press("Enter")
        expect(page.locator('svg[data-diagram="components"]')).to_be_visible()
        tab_to(page, '#diagram-list [data-diagram="activity-main"]', back=True)
        page.keyboard.press("Enter")
        expect(page.locator('svg[data-diagram="activity-main"]')).to_be_visible()

        # the start node by Tab (the focus is seen), space selects it
        tab_to(page, node(lane, start))
        page.keyboard.press(" ")
        expect(page.locator(node(lane, start))).to_have_class(re.compile(r"(^|\s)selected(\s|$)"))
        ring = page.locator(node(lane, start) + " .shape").evaluate(
            "(e) => getComputedStyle(e).strokeDasharray")
        assert ring not in ("none", ""), ring
        shot(page, "studio-keyboard-focus.png")

        # palette: an action after the selected start, wired in; its call typed in the field it focuses
        tab_to(page, '#palette .item[data-kind="action"]', back=True)  # Tab passes nodes: no selection
        page.keyboard.press("Enter")
        settled(page)
        expect(page.locator(edge(lane, start, "action1"))).to_have_count(1)
        expect(page.locator(edge(lane, "action1", end))).to_have_count(1)
        assert has_focus(page, "#props input")  # the new node's name field
        tab_to(page, '#props input[name="call"]')
        page.keyboard.type("LeftActuator.enabled(true)", delay=10)
        page.keyboard.press("Escape")  # closes the completion list, if open
        if has_focus(page, '#props input[name="call"]'):
            page.keyboard.press("Escape")  # leaves the field: it is sent, the focus is on the diagram
        settled(page)
        expect(page.locator(node(lane, "action1") + " text.label")).to_have_text("LeftActuator.enabled(true)")
        assert has_focus(page, node(lane, "action1"))  # back on the node (the redraw kept it)

        # a decision after the action; connected back to the action by keyboard, its guard typed
        tab_to(page, '#palette .item[data-kind="decision"]', back=True)
        page.keyboard.press("Enter")
        settled(page)
        expect(page.locator(edge(lane, "action1", "decision1"))).to_have_count(1)
        tab_to(page, '#props [name="connect"]')
        page.keyboard.press("Enter")  # Connect to…: the focus goes to the decision on the diagram
        assert has_focus(page, node(lane, "decision1"))
        tab_to(page, node(lane, "action1"), back=True)
        page.keyboard.press("Enter")
        settled(page)
        expect(page.locator(edge(lane, "decision1", "action1"))).to_have_count(1)
        assert has_focus(page, '#props input[name="guard"][data-target="action1"]')
        page.keyboard.type("not Application.exit", delay=10)
        page.keyboard.press("Escape")
        if has_focus(page, '#props input[name="guard"]'):
            page.keyboard.press("Escape")
        settled(page)
        guard = page.locator(edge(lane, "decision1", "action1") + " text.guard")
        expect(guard).to_have_text("not Application.exit")

        # rename: Enter on the node goes to its name field
        tab_to(page, node(lane, "action1"))
        page.keyboard.press("Enter")
        assert has_focus(page, '#props input[name="rename"]')
        page.keyboard.press("Control+a")
        page.keyboard.type("motors_on", delay=10)
        page.keyboard.press("Enter")
        settled(page)
        expect(page.locator(node(lane, "motors_on"))).to_have_count(1)
        expect(page.locator(node(lane, "action1"))).to_have_count(0)

        # delete the decision (Delete takes the node that has the focus), undo, redo
        page.keyboard.press("Escape")
        tab_to(page, node(lane, "decision1"))
        page.keyboard.press("Delete")
        settled(page)
        expect(page.locator(node(lane, "decision1"))).to_have_count(0)
        page.keyboard.press("Control+z")
        settled(page)
        expect(page.locator(node(lane, "decision1"))).to_have_count(1)
        page.keyboard.press("Control+Shift+z")
        settled(page)
        expect(page.locator(node(lane, "decision1"))).to_have_count(0)

        # a swimlane: its form by Tab, typed, Enter; it starts wired start -> end
        tab_to(page, '#palette [name="lane-name"]')
        page.keyboard.type("Blink", delay=10)
        page.keyboard.press("Enter")
        settled(page)
        expect(page.locator(edge("Blink", "start", "end"))).to_have_count(1)
        expect(page.locator('svg[data-diagram="activity-blink"]')).to_be_visible()  # its new diagram is shown
        tab_to(page, '#diagram-list [data-diagram="activity-main"]', back=True)
        page.keyboard.press("Enter")
        expect(page.locator('svg[data-diagram="activity-main"]')).to_be_visible()

        # zoom and pan by keys (from the diagram); f fits
        tab_to(page, node(lane, "motors_on"))
        before = viewport(page)
        page.keyboard.press("+")
        zoomed = viewport(page)
        assert zoomed != before
        assert scale(zoomed) > scale(before)
        page.keyboard.press("ArrowRight")
        assert viewport(page) != zoomed and scale(viewport(page)) == scale(zoomed)
        page.keyboard.press("-")
        assert scale(viewport(page)) < scale(zoomed)
        expect(page.locator("#follow")).to_have_attribute("aria-pressed", "false")  # moved by hand
        page.keyboard.press("l")
        expect(page.locator("#follow")).to_have_attribute("aria-pressed", "true")

        # save
        page.keyboard.press("Control+s")
        expect(page.locator("#save")).to_have_attribute("data-dirty", "false")
        main = (folder / "activities" / "main.yaml").read_text(encoding="utf-8")
        assert "motors_on" in main and "LeftActuator.enabled(true)" in main and "decision1" not in main, main
        assert (folder / "activities" / "blink.yaml").is_file()
        assert errors == [], errors
        page.close()
