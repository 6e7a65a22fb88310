"""What the editor draws after edits in the page, in a real browser (Debian's Chromium, Playwright).

A new datastore, send and accept node is labelled with what is written (nothing made up); a link
added in the component diagram goes around the other components and leaves the ports' labels
readable; a node the user dragged and the nodes added after it never overlap, and no flow runs
through a node; the swimlane form offers only the files a lane can be added to. Screenshots
under out/.
"""

from __future__ import annotations

import itertools
import shutil
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from playwright.sync_api import Browser, Page, expect
from robot_run import CAR_MODEL
from studio_support import chromium, shot, studio
from test_studio_edit_browser import (
    click_kind,
    click_node,
    connect,
    node,
    open_page,
    selected_node,
    settled,
    show,
)

#: In each lane of diagram `d`: the pairs of nodes whose boxes overlap, and the flows that run
#: through a node other than their own two (sampled every 2 px along the drawn path).
ACTIVITY_JS = """(d) => {
  const out = {overlaps: [], through: [], nodes: 0, edges: 0};
  for (const lane of document.querySelectorAll(`svg[data-diagram="${d}"] g.lane`)) {
    const boxes = [...lane.querySelectorAll('g.node')].map((g) => ({id: g.dataset.node,
      x: +g.dataset.x, y: +g.dataset.y, w: +g.dataset.w, h: +g.dataset.h}));
    out.nodes += boxes.length;
    for (let i = 0; i < boxes.length; i++) for (let j = i + 1; j < boxes.length; j++) {
      const a = boxes[i], b = boxes[j];
      const meet = a.x < b.x + b.w && b.x < a.x + a.w && a.y < b.y + b.h && b.y < a.y + a.h;
      if (meet) out.overlaps.push(`${a.id}/${b.id}`);
    }
    for (const e of lane.querySelectorAll('g.edge')) {
      out.edges += 1;
      const path = e.querySelector('path.line');
      const len = path.getTotalLength();
      for (const b of boxes) {
        if (b.id === e.dataset.source || b.id === e.dataset.target) continue;
        for (let s = 0; s <= len; s += 2) {
          const p = path.getPointAtLength(s);
          if (p.x > b.x + 2 && p.x < b.x + b.w - 2 && p.y > b.y + 2 && p.y < b.y + b.h - 2) {
            out.through.push(`${e.dataset.source}->${e.dataset.target} through ${b.id}`);
            break;
          }
        }
      }
    }
  }
  return out;
}"""

#: The component diagram: the links that run through a component other than their own two, the
#: port labels another component's box covers, and the port labels a link runs through.
COMPONENTS_JS = """() => {
  const svg = document.querySelector('svg[data-diagram="components"]');
  const comps = [...svg.querySelectorAll('g.component')].map((g) => {
    const b = g.querySelector('rect.box');
    const x = +g.dataset.x, y = +g.dataset.y;
    const labels = [...g.querySelectorAll('text.port-label')].map((t) => {
      const r = t.getBBox();
      return {text: t.textContent, x: r.x + x, y: r.y + y, w: r.width, h: r.height};
    });
    const w = +b.getAttribute('width'), h = +b.getAttribute('height');
    return {name: g.dataset.component, x, y, w, h, labels};
  });
  const inside = (p, r, m) => p.x > r.x + m && p.x < r.x + r.w - m && p.y > r.y + m && p.y < r.y + r.h - m;
  const out = {through: [], covered: [], crossed: [], links: 0};
  for (const g of svg.querySelectorAll('g.link')) {
    out.links += 1;
    const path = g.querySelector('path.line');
    const len = path.getTotalLength();
    const pts = [];
    for (let s = 0; s <= len; s += 2) pts.push(path.getPointAtLength(s));
    for (const c of comps) {
      if (pts.some((p) => inside(p, c, 2))) out.through.push(`${g.dataset.link} through ${c.name}`);
      for (const l of c.labels) {
        if (pts.some((p) => inside(p, l, 1))) out.crossed.push(`${g.dataset.link} over ${l.text}`);
      }
    }
  }
  for (const c of comps) for (const l of c.labels) for (const o of comps) {
    if (o === c) continue;
    const meet = l.x < o.x + o.w && o.x < l.x + l.w && l.y < o.y + o.h && o.y < l.y + l.h;
    if (meet) out.covered.push(`${l.text} under ${o.name}`);
  }
  return out;
}"""


@pytest.fixture(scope="module")
def browser() -> Iterator[Browser]:
    with chromium() as launched:
        yield launched


def new_model(page: Page, name: str) -> None:
    page.locator('#new-model-form [name="model-name"]').fill(name)
    page.locator("#new-model").click()
    settled(page)


def drawn(page: Page) -> None:
    """The shown diagram draws the answer of the last edit."""
    settled(page)
    page.wait_for_function("window.__studio.edit.drawn === window.__studio.edit.version")


def has_label(page: Page, lane: str, node_id: str, text: str) -> None:
    """The node is drawn with the label `text` (once the answer of the last edit is drawn)."""
    expect(page.locator(node(page, lane, node_id)).locator("text.label")).to_have_text(text)


def lane_file_choices(page: Page) -> list[str]:
    return [str(x) for x in page.locator('#palette select[name="lane-file"] option').all_text_contents()]


def test_new_nodes_show_what_is_written_and_lanes_go_only_where_a_lane_list_is(
        browser: Browser, tmp_path: Path) -> None:
    errors: list[str] = []
    lane = "RaspberryPI"
    with studio(["studio", "--new", str(tmp_path / "bot"), "--port", "0"], tmp_path) as proc:
        page = open_page(browser, proc.url, errors)
        new_model(page, "bot")
        show(page, "activity-main")
        # the starter's main.yaml is one lane (no `lanes:` list): a new lane goes to a file of its own
        assert lane_file_choices(page) == ["in a new file"]
        click_node(page, lane, "start")
        added: dict[str, str] = {}
        for kind in ("datastore", "send", "accept"):
            click_kind(page, kind)
            added[kind] = selected_node(page)
        has_label(page, lane, added["datastore"], added["datastore"])
        has_label(page, lane, added["send"], "send")
        has_label(page, lane, added["accept"], "accept")
        shot(page, "studio-drawing-new-nodes.png")
        labels = page.locator("svg.diagram g.node text.label").all_text_contents()
        assert not [x for x in labels if "None" in x], labels
        for kind, field, value in (("datastore", "name", "stopped"), ("send", "signal", "halted"),
                                   ("accept", "signal", "go")):
            click_node(page, lane, added[kind])
            box = page.locator(f'#props input[name="{field}"]')
            box.fill(value)
            box.press("Enter")
            settled(page)
        has_label(page, lane, added["datastore"], "stopped")
        has_label(page, lane, added["send"], "send halted")
        has_label(page, lane, added["accept"], "accept go")
        click_node(page, lane, added["datastore"])
        value_field = page.locator('#props input[name="value"]')
        value_field.fill("true")
        value_field.press("Enter")
        settled(page)
        has_label(page, lane, added["datastore"], "stopped = true")
        page.close()
    # a model with `lanes:` lists (the car's measure.yaml and motion.yaml): those are offered
    folder = tmp_path / "car"
    shutil.copytree(CAR_MODEL, folder)
    with studio(["studio", str(folder), "--port", "0"], tmp_path) as proc:
        page = open_page(browser, proc.url, errors)
        show(page, "activity-main")
        assert lane_file_choices(page) == ["in a new file", "in activities/measure.yaml",
                                           "in activities/motion.yaml"]
        page.locator('#palette [name="lane-name"]').fill("Wait")
        page.locator('#palette select[name="lane-file"]').select_option("activities/motion.yaml")
        page.locator('#palette [data-action="add-lane"]').click()
        settled(page)
        expect(page.locator('#notice[data-kind="error"]')).to_be_hidden()
        expect(page.locator('svg[data-diagram="activity-motion"] g.lane[data-lane="Wait"]')).to_have_count(1)
        page.close()
    assert errors == [], errors


def test_a_link_added_in_the_page_goes_around_the_components_and_keeps_the_port_labels_readable(
        browser: Browser, tmp_path: Path) -> None:
    errors: list[str] = []
    with studio(["studio", "--new", str(tmp_path / "buggy"), "--port", "0"], tmp_path) as proc:
        page = open_page(browser, proc.url, errors)
        new_model(page, "buggy")
        show(page, "components")
        page.locator('#palette [data-impl="passive_buzzer"]').click()
        page.locator('#props [name="name"]').fill("Horn")
        page.locator('#props [name="setting-gpio"]').fill("17")
        page.locator('#props [name="add"]').click()
        settled(page)
        expect(page.locator('g.component[data-component="Horn"]')).to_have_count(1)
        page.locator('#props [name="port"]').fill("beep")
        page.locator('#props [name="port-feature"]').select_option("tone")
        page.locator('#props [name="add-port"]').click()
        settled(page)
        page.locator('#props [name="link-to"]').select_option("DistanceRead.range")
        page.locator('#props [name="add-link"]').click()
        settled(page)
        expect(page.locator('g.link[data-link="link1"]')).to_have_count(1)
        drawn(page)
        shot(page, "studio-drawing-link.png")
        found: dict[str, Any] = page.evaluate(COMPONENTS_JS)
        assert found["links"] == 1
        assert found["through"] == [] and found["covered"] == [] and found["crossed"] == [], found
        page.close()
    assert errors == [], errors


def test_a_dragged_node_and_nodes_added_after_it_never_overlap_and_no_flow_runs_through_a_node(
        browser: Browser, tmp_path: Path) -> None:
    errors: list[str] = []
    lane = "RaspberryPI"
    with studio(["studio", "--new", str(tmp_path / "buggy"), "--port", "0"], tmp_path) as proc:
        page = open_page(browser, proc.url, errors)
        new_model(page, "buggy")
        show(page, "activity-main")
        click_node(page, lane, "start")
        click_kind(page, "action")
        first = selected_node(page)
        connect(page, lane, "start", first)
        connect(page, lane, first, "end")
        # the user drags it to the right and a little down
        box = page.locator(node(page, lane, first)).bounding_box()
        assert box
        page.mouse.move(box["x"] + box["width"] / 2, box["y"] + box["height"] / 2)
        page.mouse.down()
        page.mouse.move(box["x"] + box["width"] / 2 + 120, box["y"] + box["height"] / 2 + 40, steps=10)
        page.mouse.up()
        settled(page)
        pinned = page.locator(node(page, lane, first))
        at = pinned.get_attribute("data-x"), pinned.get_attribute("data-y")
        # five actions more, chained in front of the dragged one: start -> a2 .. a6 -> first
        chain = ["start"]
        for call in ("LeftActuator.dutycycle(60)", "RightActuator.dutycycle(60)",
                     "LeftActuator.enabled(true)", "RightActuator.enabled(true)", "msleep(1500)"):
            page.locator(f'svg.diagram g.lane[data-lane="{lane}"] .lane-title').first.click()
            click_kind(page, "action")
            chain.append(selected_node(page))
            call_field = page.locator('#props input[name="call"]')
            call_field.fill(call)
            call_field.press("Enter")
            settled(page)
        chain.append(first)
        for source, target in itertools.pairwise(chain):
            connect(page, lane, source, target)
        drawn(page)
        shot(page, "studio-drawing-dragged.png")
        assert (pinned.get_attribute("data-x"), pinned.get_attribute("data-y")) == at  # kept where it was put
        found: dict[str, Any] = page.evaluate(ACTIVITY_JS, "activity-main")
        assert found["nodes"] == 8 and found["edges"] == 7, found
        assert found["overlaps"] == [] and found["through"] == [], found
        # a new page lays the lane out afresh (the chain first, the dragged node last) and puts the
        # dragged node where it was put: the others make room for it
        page.reload()
        page.wait_for_function("window.__studio && window.__studio.ready === true && !!window.__studio.edit")
        show(page, "activity-main")
        drawn(page)
        shot(page, "studio-drawing-dragged-reloaded.png")
        assert (pinned.get_attribute("data-x"), pinned.get_attribute("data-y")) == at
        found = page.evaluate(ACTIVITY_JS, "activity-main")
        assert found["nodes"] == 8 and found["edges"] == 7, found
        assert found["overlaps"] == [] and found["through"] == [], found
        page.close()
    assert errors == [], errors
