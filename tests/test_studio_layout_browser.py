"""Layout stability while editing, in a real browser (Debian's Chromium driven by Playwright).

On the reference car's `main` (one lane of ~60 nodes with loops, where ELK laid the whole lane out
afresh and moved every node by hundreds of px when one was added), adding a node, connecting it
and renaming another leave every node drawn before where it was; a node the user dragged keeps
its place (the layout file) through an unrelated edit and a reload.
"""

from __future__ import annotations

import shutil
from collections.abc import Iterator
from pathlib import Path

import pytest
from playwright.sync_api import Browser, Page, expect
from robot_run import CAR_MODEL
from studio_support import chromium, studio
from test_studio_edit_browser import (
    connect,
    drag_kind_onto_lane,
    node,
    open_page,
    selected_node,
    settled,
    show,
)

TOLERANCE_PX = 2.0
#: every node's place in the diagram: its lane's offset plus its own (data-x, data-y)
PLACES_JS = """(d) => {
  const out = {};
  for (const g of document.querySelectorAll(`svg[data-diagram="${d}"] g.node`)) {
    const at = g.closest('g.lane').getAttribute('transform') || '';
    const m = /translate\\(([-\\d.e]+),([-\\d.e]+)\\)/.exec(at);
    const dx = m ? Number(m[1]) : 0, dy = m ? Number(m[2]) : 0;
    out[g.getAttribute('data-lane') + '/' + g.getAttribute('data-node')] = [
      Number(g.getAttribute('data-x')) + dx, Number(g.getAttribute('data-y')) + dy];
  }
  return out;
}"""


@pytest.fixture(scope="module")
def browser() -> Iterator[Browser]:
    with chromium() as launched:
        yield launched


def places(page: Page, diagram: str) -> dict[str, tuple[float, float]]:
    return {k: (v[0], v[1]) for k, v in page.evaluate(PLACES_JS, diagram).items()}


def moved(before: dict[str, tuple[float, float]], after: dict[str, tuple[float, float]],
          renamed: dict[str, str] | None = None) -> dict[str, tuple[float, float]]:
    """The nodes of `before` that are not within TOLERANCE_PX of their place in `after`."""
    out: dict[str, tuple[float, float]] = {}
    for key, (x, y) in before.items():
        now = after[(renamed or {}).get(key, key)]
        if max(abs(now[0] - x), abs(now[1] - y)) > TOLERANCE_PX:
            out[key] = (round(now[0] - x), round(now[1] - y))
    return out


def place_of(page: Page, lane: str, node_id: str) -> tuple[float, float]:
    g = page.locator(node(page, lane, node_id))
    return float(g.get_attribute("data-x") or "nan"), float(g.get_attribute("data-y") or "nan")


#: a region opened lays its lane out afresh (ELK, seconds on a loaded machine)
WAIT_MS = 30_000


def open_region(page: Page, lane: str, region: str, inside: str) -> None:
    """Open a collapsed region (docs/studio.md) as a user does: brought into view, a click on its box."""
    page.evaluate("([lane, region]) => window.__studio.reveal(lane, region)", [lane, region])
    page.locator(node(page, lane, region)).click()
    expect(page.locator(node(page, lane, inside))).to_have_count(1, timeout=WAIT_MS)


def test_editing_a_big_lane_leaves_the_nodes_drawn_before_in_their_places(
        browser: Browser, tmp_path: Path) -> None:
    folder = tmp_path / "car"
    shutil.copytree(CAR_MODEL, folder)
    errors: list[str] = []
    lane = "RaspberryPI"
    with studio(["studio", str(folder), "--port", "0"], tmp_path) as proc:
        page = open_page(browser, proc.url, errors)
        show(page, "activity-main")
        # `look` and `creep` are in the no-room look, collapsed at the opening view: opened first
        open_region(page, lane, "region:forget_sides", "look")
        page.keyboard.press("f")
        start = places(page, "activity-main")
        assert len(start) > 50
        drag_kind_onto_lane(page, "action", lane)
        new = selected_node(page)
        added = places(page, "activity-main")
        assert f"{lane}/{new}" in added and len(added) == len(start) + 1
        assert moved(start, added) == {}
        # the new node is in its lane, below what was there
        lane_w = float(page.locator(f'svg.diagram g.lane[data-lane="{lane}"] rect.lane-bg').first
                       .get_attribute("width") or "nan")
        x, y = place_of(page, lane, new)
        assert 0 <= x <= lane_w and y > max(p[1] for p in start.values()), (x, y, lane_w)
        connect(page, lane, "look", new)
        assert moved(added, places(page, "activity-main")) == {}
        # a rename is an edit of the lane's text too
        page.locator(node(page, lane, "creep")).dblclick()
        name = page.locator('#props input[name="rename"]')
        name.fill("creep_on")
        name.press("Enter")
        settled(page)
        expect(page.locator(node(page, lane, "creep_on"))).to_have_count(1)
        assert moved(added, places(page, "activity-main"), {f"{lane}/creep": f"{lane}/creep_on"}) == {}
        assert errors == [], errors
        page.close()


def test_a_dragged_node_keeps_its_place_through_an_unrelated_edit_and_a_reload(
        browser: Browser, tmp_path: Path) -> None:
    folder = tmp_path / "car"
    shutil.copytree(CAR_MODEL, folder)
    errors: list[str] = []
    lane = "RaspberryPI"
    with studio(["studio", str(folder), "--port", "0"], tmp_path) as proc:
        page = open_page(browser, proc.url, errors)
        show(page, "activity-main")
        open_region(page, lane, "region:forget_sides", "look")  # `look` is inside, collapsed
        page.keyboard.press("f")
        dragged = page.locator(node(page, lane, "finish"))
        before = place_of(page, lane, "finish")
        box = dragged.bounding_box()
        assert box
        page.mouse.move(box["x"] + box["width"] / 2, box["y"] + box["height"] / 2)
        page.mouse.down()
        page.mouse.move(box["x"] + box["width"] / 2 - 80, box["y"] + box["height"] / 2 + 60, steps=8)
        page.mouse.up()
        settled(page)
        there = place_of(page, lane, "finish")
        assert there[0] < before[0] - 20 and there[1] > before[1] + 20, (before, there)
        others = {k: v for k, v in places(page, "activity-main").items() if k != f"{lane}/finish"}
        # an unrelated edit: a new node, connected
        drag_kind_onto_lane(page, "action", lane)
        new = selected_node(page)
        connect(page, lane, "look", new)
        assert place_of(page, lane, "finish") == there
        assert moved(others, places(page, "activity-main")) == {}
        page.keyboard.press("Control+s")
        expect(page.locator("#save")).to_have_attribute("data-dirty", "false")
        page.reload()
        page.wait_for_function("window.__studio && window.__studio.ready === true && !!window.__studio.edit")
        show(page, "activity-main")
        # reloaded, the page opens as at first: the new node, after `look`, may be in a collapsed
        # region; shown as a diagnostic's click shows a node (its region opens)
        page.evaluate("([lane, id]) => window.__studio.reveal(lane, id)", [lane, new])
        expect(page.locator(node(page, lane, new))).to_have_count(1, timeout=WAIT_MS)
        assert place_of(page, lane, "finish") == there
        assert errors == [], errors
        page.close()
