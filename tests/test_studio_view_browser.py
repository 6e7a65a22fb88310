"""What a person sees when a diagram opens in umlbot studio (Debian's Chromium driven by Playwright).

Readable first view of a big diagram, guards on their own flows, flows that go down, lane headers
whose texts do not overlap, a small window, and a component diagram that stays put when a part is
added. Each test reads the drawn page (computed styles, bounding boxes); screenshots under out/.
"""

from __future__ import annotations

import shutil
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from playwright.sync_api import Browser, FloatRect, Page, expect
from robot_run import CAR_MODEL
from studio_support import chromium, shot, studio

WAIT_MS = 30_000

#: a lane whose end node is written second, and a loop through a decision written below its target
FLOW_MODEL = """\
name: flow
components:
  Motor: {kind: actuator}
lanes:
  - lane: Motor
    nodes:
      - {id: start, kind: start, next: on}
      - {id: end, kind: end}
      - {id: off, kind: action, call: Motor.enabled(false), next: running}
      - {id: running, kind: decision, branches: [{if: Application.exit, then: end}, {else: off}]}
      - {id: on, kind: action, call: Motor.enabled(true), next: running}
deployment:
  driver: mock
  components:
    Motor: {impl: l298n, settings: {in1: 22, in2: 23}}
"""


#: the starter model's shape: one narrow lane (start -> end) on a component
NARROW_MODEL = """\
name: narrow
components:
  RaspberryPI: {kind: system}
lanes:
  - lane: RaspberryPI
    nodes:
      - {id: start, kind: start}
      - {id: end, kind: end}
deployment:
  driver: mock
  components:
    RaspberryPI: {impl: raspberrypi, settings: {pins: []}}
"""


@pytest.fixture(scope="module")
def browser() -> Iterator[Browser]:
    with chromium() as launched:
        yield launched


def open_page(browser: Browser, url: str, width: int = 1600, height: int = 1000) -> Page:
    page = browser.new_page(viewport={"width": width, "height": height})
    errors: list[str] = []
    page.on("pageerror", lambda exc: errors.append(str(exc)))
    page.goto(url)
    page.set_default_timeout(WAIT_MS)
    page.wait_for_function("window.__studio && window.__studio.ready === true")
    assert errors == [], errors
    return page


def show(page: Page, diagram: str) -> None:
    page.locator(f'#diagram-list [data-diagram="{diagram}"]').click()
    expect(page.locator(f'svg[data-diagram="{diagram}"]')).to_be_visible()


def canvas_box(page: Page) -> FloatRect:
    box = page.locator("#canvas").bounding_box()
    assert box
    return box


def visible_texts(page: Page, diagram: str, css: str) -> list[dict[str, Any]]:
    """The texts matching `css` that are drawn inside the canvas: their text, display and height."""
    result: list[dict[str, Any]] = page.evaluate(
        """([diagram, css]) => {
          const c = document.querySelector('#canvas').getBoundingClientRect();
          const svg = document.querySelector(`svg[data-diagram="${diagram}"]`);
          return [...svg.querySelectorAll(css)].map((t) => {
            const b = t.getBoundingClientRect();
            const inside = b.top >= c.top && b.bottom <= c.bottom && b.left >= c.left && b.right <= c.right;
            return { text: t.textContent, display: getComputedStyle(t).display, h: b.height, inside };
          }).filter((t) => t.inside || t.display === 'none');
        }""", [diagram, css])
    return result


def test_the_cars_main_diagram_opens_readable_at_its_start_and_fit_shows_all_of_it(browser: Browser,
                                                                                 tmp_path: Path) -> None:
    with studio(["studio", str(CAR_MODEL), "--port", "0"], tmp_path) as proc:
        page = open_page(browser, proc.url)
        assert page.locator("#diagram-list li.selected").get_attribute("data-diagram") == "activity-main"
        svg = page.locator('svg[data-diagram="activity-main"]')
        # 100+ nodes: not fitted whole (that hid every name), but readable, from its start node
        start = svg.locator('g.node[data-node="start"]').bounding_box()
        canvas = canvas_box(page)
        assert start and canvas["y"] <= start["y"] <= canvas["y"] + canvas["height"] / 3, (start, canvas)
        assert canvas["x"] <= start["x"] <= canvas["x"] + canvas["width"]
        drawn = visible_texts(page, "activity-main", "g.node text.label")
        labels = [t for t in drawn if t["display"] != "none"]
        names = {t["text"] for t in labels}
        assert len(labels) >= 8 and "speed_percent = 70" in names, names
        assert min(t["h"] for t in labels) >= 10, labels  # 13 px names drawn at >= 0.8
        stats = visible_texts(page, "activity-main", "g.node text.stats")
        assert stats and all(t["display"] != "none" for t in stats), stats
        shot(page, "studio-view-main-open.png")
        # Fit (f) shows the whole diagram
        page.keyboard.press("f")
        whole = svg.locator("g.viewport").bounding_box()
        assert whole
        top, bottom = canvas["y"] - 1, canvas["y"] + canvas["height"] + 1
        left, right = canvas["x"] - 1, canvas["x"] + canvas["width"] + 1
        assert top <= whole["y"] <= whole["y"] + whole["height"] <= bottom, (whole, canvas)
        assert left <= whole["x"] <= whole["x"] + whole["width"] <= right, (whole, canvas)
        page.close()


GUARD_GEOMETRY = """
(diagram) => {
  const svg = document.querySelector(`svg[data-diagram="${diagram}"]`);
  const out = [];
  for (const lane of svg.querySelectorAll('g.lane')) {
    const edges = [...lane.querySelectorAll('g.edge')].map((g) => {
      const path = g.querySelector('path.line');
      const pts = [];
      const n = path.getTotalLength();
      for (let s = 0; s <= n; s += 2) pts.push(path.getPointAtLength(s));
      return { g, pts };
    });
    for (const e of edges) {
      const label = e.g.querySelector('text.elabel');
      if (!label) continue;
      const b = label.getBBox();  // the label's box in the lane's units (as the paths' points)
      const cx = b.x + b.width / 2;
      const cy = b.y + b.height / 2;
      const dist = (pts) => Math.min(...pts.map((p) => Math.hypot(p.x - cx, p.y - cy)));
      const inBox = (pts) => pts.some((p) => p.x > b.x + 1 && p.x < b.x + b.width - 1
                                          && p.y > b.y + 1 && p.y < b.y + b.height - 1);
      const others = edges.filter((o) => o !== e);
      out.push({
        lane: lane.dataset.lane, source: e.g.dataset.source, target: e.g.dataset.target,
        text: label.textContent,
        title: e.g.querySelector('title')?.textContent ?? null, own: dist(e.pts),
        other: others.length ? Math.min(...others.map((o) => dist(o.pts))) : 1e9,
        crossed: others.filter((o) => inBox(o.pts)).map((o) => o.g.dataset.target),
      });
    }
  }
  return out;
}
"""


def test_a_guard_sits_on_its_own_flow_and_a_long_one_is_cut_with_its_full_text_as_tooltip(
        browser: Browser, tmp_path: Path) -> None:
    with studio(["studio", str(CAR_MODEL), "--port", "0"], tmp_path) as proc:
        page = open_page(browser, proc.url)
        guards: list[dict[str, Any]] = page.evaluate(GUARD_GEOMETRY, "activity-main")
        assert len(guards) >= 15, guards
        for g in guards:
            # the flow runs through its label; no other flow comes as near or through it
            assert g["own"] <= 3, g
            assert g["other"] > g["own"] + 6, g
            assert g["crossed"] == [], g
        cut = [g for g in guards if g["text"].endswith("…")]
        assert cut, guards
        for g in cut:
            assert g["title"] and g["title"].startswith(g["text"][:-1]), g
            assert len(g["title"]) > len(g["text"]), g
        # the loop's exit guard names the flow to the Stop action, next to its decision
        exit_guard = next(g for g in guards if g["source"] == "running" and g["text"] == "Application.exit")
        assert exit_guard["target"] == "finish", exit_guard
        shot(page, "studio-view-guards.png")
        page.close()


def node_box(page: Page, lane: str, node: str) -> FloatRect:
    box = page.locator(f'svg.diagram g.node[data-lane="{lane}"][data-node="{node}"]').bounding_box()
    assert box, node
    return box


def test_flows_go_down_whatever_order_the_nodes_are_written_in(browser: Browser, tmp_path: Path) -> None:
    folder = tmp_path / "flow"
    folder.mkdir()
    (folder / "model.yaml").write_text(FLOW_MODEL, encoding="utf-8")
    with studio(["studio", str(folder), "--port", "0"], tmp_path) as proc:
        page = open_page(browser, proc.url)
        show(page, "activity-model")
        start, on, running, off, end = (node_box(page, "Motor", n)
                                        for n in ("start", "on", "running", "off", "end"))
        # start -> on -> running -> (exit) end, (else) off -> back to running: each below the one before
        assert start["y"] + start["height"] <= on["y"], (start, on)
        assert on["y"] + on["height"] <= running["y"], (on, running)
        assert running["y"] + running["height"] <= end["y"], (running, end)
        assert running["y"] + running["height"] <= off["y"], (running, off)
        # and the arrows into end and off come from above: their paths end at the node's top
        for target in ("end", "off"):
            tip = page.evaluate(
                """(t) => {
                  const p = document.querySelector(
                    `g.edge[data-lane="Motor"][data-source="running"][data-target="${t}"] path.line`);
                  const q = p.getPointAtLength(p.getTotalLength());
                  const before = p.getPointAtLength(p.getTotalLength() - 4);
                  return { dy: q.y - before.y }; }""", target)
            assert tip["dy"] > 0, (target, tip)  # the last stretch points down
        shot(page, "studio-view-flow-down.png")
        page.close()


def header_boxes(page: Page, diagram: str) -> list[dict[str, Any]]:
    """Each lane's stereotype and name boxes (x, y, width, height) in the lane's units."""
    boxes: list[dict[str, Any]] = page.evaluate(
        """(d) => [...document.querySelectorAll(`svg[data-diagram="${d}"] g.lane`)].map((g) => {
             const a = g.querySelector('text.lane-sub')?.getBBox();
             const b = g.querySelector('text.lane-title').getBBox();
             return { lane: g.dataset.lane, sub: a ? [a.x, a.y, a.width, a.height] : null,
                      title: [b.x, b.y, b.width, b.height] }; })""",
        diagram)
    return boxes


def test_a_lane_headers_stereotype_and_name_do_not_overlap(browser: Browser, tmp_path: Path) -> None:
    folder = tmp_path / "narrow"
    folder.mkdir()
    (folder / "model.yaml").write_text(NARROW_MODEL, encoding="utf-8")
    headers: list[dict[str, Any]] = []
    # a narrow component lane (the starter model's: its header overlapped), the car's wide
    # component lane and its virtual lanes («activity»)
    for model, diagrams in ((folder, ("activity-model",)),
                            (CAR_MODEL, ("activity-main", "activity-measure"))):
        with studio(["studio", str(model), "--port", "0"], tmp_path) as proc:
            page = open_page(browser, proc.url)
            for diagram in diagrams:
                show(page, diagram)
                headers += header_boxes(page, diagram)
                shot(page, f"studio-view-header-{model.name}.png")
            page.close()
    assert {h["lane"] for h in headers} >= {"RaspberryPI", "Measure", "Glance"}, headers
    for h in headers:
        assert h["sub"], h
        ax, ay, aw, ah = h["sub"]
        bx, by, bw, bh = h["title"]
        overlap_x = min(ax + aw, bx + bw) - max(ax, bx)
        overlap_y = min(ay + ah, by + bh) - max(ay, by)
        assert overlap_x <= 0 or overlap_y <= 0, h


def test_a_laptop_window_gives_the_diagram_most_of_the_width_and_opens_it_readable(
        browser: Browser, tmp_path: Path) -> None:
    with studio(["studio", str(CAR_MODEL), "--port", "0"], tmp_path) as proc:
        page = open_page(browser, proc.url, 1280, 720)
        assert canvas_box(page)["width"] >= 0.55 * 1280
        for diagram, css, px in (("components", "g.component text.impl", 8.0),
                                 ("components", "g.component text.name", 11.0),
                                 ("activity-motion", "g.node text.label", 10.0),
                                 ("activity-measure", "g.node text.label", 10.0)):
            show(page, diagram)
            texts = visible_texts(page, diagram, css)
            assert texts and all(t["display"] != "none" for t in texts), (diagram, texts)
            assert min(t["h"] for t in texts) >= px, (diagram, css, texts)
            shot(page, f"studio-view-1280-{diagram}.png")
        # the mark of an action that calls an activity is big enough to see (and click)
        show(page, "activity-main")
        rakes = page.evaluate("""() => [...document.querySelectorAll('svg.diagram path.rake')]
                                 .map((r) => r.getBoundingClientRect()).filter((b) => b.width > 0)
                                 .map((b) => [b.width, b.height])""")
        assert rakes and min(min(w, h) for w, h in rakes) >= 11, rakes
        page.close()


def component_boxes(page: Page) -> dict[str, tuple[float, float, float, float]]:
    """Each component's box in the diagram's units."""
    boxes: dict[str, list[float]] = page.evaluate(
        """() => Object.fromEntries([...document.querySelectorAll('svg.diagram g.component')]
             .map((g) => {
               const b = g.querySelector('rect.box').getBBox();
               return [g.dataset.component, [Number(g.dataset.x), Number(g.dataset.y), b.width, b.height]];
             }))""")
    return {name: (b[0], b[1], b[2], b[3]) for name, b in boxes.items()}


def test_adding_a_component_and_a_link_leaves_the_other_components_where_they_were(
        browser: Browser, tmp_path: Path) -> None:
    folder = tmp_path / "car"
    shutil.copytree(CAR_MODEL, folder)
    with studio(["studio", str(folder), "--port", "0"], tmp_path) as proc:
        page = open_page(browser, proc.url)
        page.wait_for_function("!!window.__studio.edit")
        show(page, "components")
        before = component_boxes(page)
        assert len(before) == 5

        def settled() -> None:
            page.wait_for_function("window.__studio.edit.busy === false && window.__studio.ready === true")

        page.locator('#palette [data-impl="servo"]').click()
        page.locator('#props [name="name"]').fill("Pan")
        page.locator('#props [name="setting-gpio"]').fill("17")
        page.locator('#props [name="add"]').click()
        settled()
        expect(page.locator('g.component[data-component="Pan"]')).to_have_count(1)
        added = component_boxes(page)
        assert {k: v for k, v in added.items() if k != "Pan"} == before
        # the new one is drawn clear of the others
        px, py, pw, ph = added["Pan"]
        for name, (x, y, w, h) in before.items():
            clear = px + pw <= x or x + w <= px or py + ph <= y or y + h <= py
            assert clear, (name, added["Pan"], before[name])
        page.locator('#props [name="port"]').fill("aim")
        page.locator('#props [name="port-feature"]').select_option("angle")
        page.locator('#props [name="add-port"]').click()
        settled()
        page.locator('#props [name="link-to"]').select_option("DistanceRead.range")
        page.locator('#props [name="add-link"]').click()
        settled()
        expect(page.locator("g.link")).to_have_count(2)
        assert component_boxes(page) == added
        shot(page, "studio-view-component-added.png")
        page.close()
