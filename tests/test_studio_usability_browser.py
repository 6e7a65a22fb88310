"""The usability script of issue 28: a new user builds a small robot with the pointer, from an
empty folder, in a real browser (Debian's Chromium driven by Playwright), runs it in the simulator
and sees it reach the end of the corridor. Every pointer action (a click, a drag) and every
keystroke is counted; the counts may not grow beyond the figures docs/studio.md gives ("The
usability script"), which the test reads from there.

The robot: both motors at 60 % and on, then, in a loop, read the sonar while the way ahead is
longer than 25 cm; near a wall (the else), both motors off and the end. What cannot be done with
the pointer is typed, and counted: the numbers (`60`, `25`, the `>`) and the closing brackets of
calls whose argument was picked from the completion list. The page is driven as a person would:
only what a person can see is clicked (Playwright's clicks wait until it is visible and still) and
the test waits only for what a person would wait for (what the page shows). Screenshots under
out/ (studio-usability-*.png).
"""

from __future__ import annotations

import re
from collections.abc import Iterator
from pathlib import Path

import pytest
from playwright.sync_api import Browser, Locator, Page, expect
from studio_support import chromium, shot, studio

REPO = Path(__file__).resolve().parent.parent
DOC = REPO / "docs" / "studio.md"
WAIT_MS = 30_000
RUN_WAIT_MS = 120_000
LANE = "RaspberryPI"


@pytest.fixture(scope="module")
def browser() -> Iterator[Browser]:
    with chromium() as launched:
        yield launched


def documented() -> tuple[int, int]:
    """The figures docs/studio.md gives: (pointer actions, keystrokes)."""
    text = DOC.read_text(encoding="utf-8")
    m = re.search(r"usability script: (\d+) pointer actions and (\d+) keystrokes", text)
    assert m, "docs/studio.md must say 'usability script: N pointer actions and M keystrokes'"
    return int(m.group(1)), int(m.group(2))


class User:
    """The new user's hands: each pointer action and keystroke goes through here and is counted."""

    def __init__(self, page: Page) -> None:
        self.page = page
        self.pointer = 0
        self.keys = 0

    def click(self, target: Locator) -> None:
        target.click()
        self.pointer += 1

    def type(self, text: str) -> None:
        self.page.keyboard.type(text, delay=30)
        self.keys += len(text)

    def drag(self, source: Locator, target: Locator) -> None:
        """One press, a move and a release: one pointer action."""
        a = source.bounding_box()
        b = target.bounding_box()
        assert a and b
        self.page.mouse.move(a["x"] + a["width"] / 2, a["y"] + a["height"] / 2)
        self.page.mouse.down()
        self.page.mouse.move(b["x"] + b["width"] / 2, b["y"] + b["height"] / 2, steps=10)
        self.page.mouse.up()
        self.pointer += 1

    def choose(self, select: Locator, value: str) -> None:
        """A native drop-down: open it, pick the entry (two pointer actions; Playwright cannot click
        into a native list, so it selects the entry for the pointer)."""
        select.select_option(value)
        self.pointer += 2


def node(lane: str, node_id: str) -> str:
    return f'svg.diagram g.node[data-lane="{lane}"][data-node="{node_id}"]'


def edge(source: str, target: str) -> str:
    return f'svg.diagram g.edge[data-lane="{LANE}"][data-source="{source}"][data-target="{target}"]'


def selected(page: Page) -> str:
    return str(page.locator("svg.diagram g.node.selected").get_attribute("data-node"))


@pytest.mark.timeout(400)
def test_a_new_user_builds_a_robot_with_the_pointer_runs_it_and_sees_it_reach_the_end(
        browser: Browser, tmp_path: Path) -> None:
    folder = tmp_path / "my_robot"  # does not exist yet
    errors: list[str] = []
    with studio(["studio", "--new", str(folder), "--port", "0"], tmp_path) as proc:
        page = browser.new_page(viewport={"width": 1280, "height": 800})
        page.on("pageerror", lambda exc: errors.append(str(exc)))
        page.set_default_timeout(WAIT_MS)
        page.goto(proc.url)
        user = User(page)
        expect(page.locator("#new-model-form")).to_be_visible()

        def the_call(node_id: str, component: str, feature: str, pick: str | None = None,
                     typed: str = "") -> None:
            """The selected action's call: its field, the component and the feature from the
            completion list, an argument picked from it or typed, the closing bracket typed."""
            user.click(page.locator('#props input[name="call"]'))
            user.click(page.locator(f'#props .completions li[data-label="{component}"]'))
            user.click(page.locator(f'#props .completions li[data-label="{feature}"]'))
            if pick:
                user.click(page.locator(f'#props .completions li[data-label="{pick}"]'))
            if typed:
                user.type(typed)

        def add_action(component: str, feature: str, pick: str | None = None, typed: str = "") -> str:
            """An action from the palette, after the selected node, with its call."""
            before = selected(page)
            user.click(page.locator('#palette .item[data-kind="action"]'))
            expect(page.locator("svg.diagram g.node.selected")).not_to_have_attribute("data-node", before)
            new = selected(page)
            the_call(new, component, feature, pick, typed)
            return new

        # 1. the starter model (the folder's name is proposed as the robot's)
        user.click(page.locator("#new-model"))
        expect(page.locator(node(LANE, "start"))).to_be_visible()
        # 2. motors at 60 % and on, then off: each added after the one before (wired in)
        user.click(page.locator(node(LANE, "start")))
        left_duty = add_action("LeftActuator", "dutycycle", typed="60)")
        right_duty = add_action("RightActuator", "dutycycle", typed="60)")
        left_on = add_action("LeftActuator", "enabled", pick="true", typed=")")
        right_on = add_action("RightActuator", "enabled", pick="true", typed=")")
        left_off = add_action("LeftActuator", "enabled", pick="false", typed=")")
        right_off = add_action("RightActuator", "enabled", pick="false", typed=")")
        # 3. a choice dropped onto the flow between "on" and "off": its first way out, to the
        #    motors off, is its else (shown so)
        user.drag(page.locator('#palette .item[data-kind="decision"]'),
                  page.locator(edge(right_on, left_off) + " path.hit"))
        expect(page.locator(edge("decision1", left_off) + " text.elabel")).to_have_text("else")
        # 4. the loop: an action reading the sonar, wired to and from the choice by dragging from
        #    the output ports; the choice's new way asks for its guard at once
        add_action("DistanceRead", "value")
        read = selected(page)
        user.drag(page.locator(node(LANE, "decision1") + " circle.port-out"), page.locator(node(LANE, read)))
        guard = page.locator(f'#props input[name="guard"][data-target="{read}"]')
        expect(guard).to_be_focused()
        user.click(page.locator('#props .completions li[data-label="DistanceRead"]'))
        user.click(page.locator('#props .completions li[data-label="value"]'))
        user.type(">25")
        user.drag(page.locator(node(LANE, read) + " circle.port-out"), page.locator(node(LANE, "decision1")))
        expect(page.locator(edge(read, "decision1"))).to_have_count(1)
        # what was built, as the diagram shows it, with no problem left
        for a, b in [("start", left_duty), (left_duty, right_duty), (right_duty, left_on),
                     (left_on, right_on), (right_on, "decision1"), ("decision1", left_off),
                     ("decision1", read), (read, "decision1"), (left_off, right_off), (right_off, "end")]:
            expect(page.locator(edge(a, b))).to_have_count(1)
        expect(page.locator(edge("decision1", read) + " text.elabel")).to_have_text("DistanceRead.value()>25")
        expect(page.locator(node(LANE, left_duty) + " text.label")).to_have_text("LeftActuator.dutycycle(60)")
        expect(page.locator(node(LANE, right_off) + " text.label")).to_have_text(
            "RightActuator.enabled(false)")
        expect(page.locator("svg.diagram g.node.error")).to_have_count(0)
        shot(page, "studio-usability-built.png")

        # 5. run it on the corridor and watch
        user.choose(page.locator("#track"), "corridor")
        user.click(page.locator("#run"))
        expect(page.locator("#sim svg")).to_be_visible()
        ended = page.locator('#notice[data-kind="run-goal"]')
        expect(ended).to_contain_text("The car reached the goal", timeout=RUN_WAIT_MS)
        expect(ended).to_contain_text("no collisions")
        assert int(page.locator(node(LANE, read)).get_attribute("data-count") or 0) > 1  # it looped
        shot(page, "studio-usability-run.png")

        pointer, keys = documented()
        print(f"usability script: {user.pointer} pointer actions and {user.keys} keystrokes")
        assert user.pointer <= pointer and user.keys <= keys, (user.pointer, user.keys)
        assert errors == [], errors
        page.close()
