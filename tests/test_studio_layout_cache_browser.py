"""The layout cache in the page (Debian's Chromium driven by Playwright): a second open of the
reference car takes its lanes' layouts from the studio server instead of running ELK and draws
every node and flow where ELK's own layout put them; the layouts shipped beside the reference
models are today's (else `make layout-cache`). The server's side: tests/test_studio_layout_cache.py.
"""

from __future__ import annotations

import json
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from playwright.sync_api import Browser, Page
from robot_run import CAR_MODEL
from studio_support import chromium, studio

from umlbot.compiler.api import check_model
from umlbot.studio.layouts import SHIPPED_NAME, read_shipped
from umlbot.studio.model_view import model_view

WAIT_MS = 60_000
STEREO_MODEL = CAR_MODEL.parent / "stereo_car"
#: every node's place and every flow's path in a diagram, by lane
DRAWN_JS = """(d) => {
  const out = {};
  const svg = document.querySelector(`svg[data-diagram="${d}"]`);
  for (const g of svg.querySelectorAll('g.node'))
    out['node ' + g.getAttribute('data-lane') + '/' + g.getAttribute('data-node')] =
      [g.closest('g.lane').getAttribute('transform'), g.getAttribute('data-x'), g.getAttribute('data-y')];
  for (const g of svg.querySelectorAll('g.edge'))
    out['flow ' + g.getAttribute('data-lane') + '/' + g.getAttribute('data-source') + '>' +
        g.getAttribute('data-target')] = [...g.querySelectorAll('path')].map(p => p.getAttribute('d'));
  return out;
}"""


@pytest.fixture(scope="module")
def browser() -> Iterator[Browser]:
    with chromium() as launched:
        yield launched


def open_page(browser: Browser, url: str, errors: list[str]) -> Page:
    """The page in a new context (nothing of an earlier open cached by the browser)."""
    context = browser.new_context(viewport={"width": 1600, "height": 1000})
    page = context.new_page()
    page.on("pageerror", lambda exc: errors.append(str(exc)))
    page.set_default_timeout(WAIT_MS)
    page.goto(url)
    page.wait_for_function("window.__studio && window.__studio.ready === true")
    return page


def layouts(page: Page) -> dict[str, int]:
    """The page's counts of lanes laid out by ELK, taken from the cache, kept by the server, and
    cached answers that did not fit (the background warm-up's counts apart)."""
    stats: dict[str, int] = page.evaluate("({...window.__studio.layouts})")
    return {k: stats[k] for k in ("elk", "cached", "kept", "unfit")}


def lanes_of(model: Path) -> int:
    """The lanes the page lays out: every lane of every activity diagram (it lays them all out)."""
    result = check_model(model)
    assert result.model is not None
    return sum(len(d["lanes"]) for d in model_view(result.model)["diagrams"])


def test_a_second_open_takes_the_layout_from_the_cache_and_draws_the_same(
        browser: Browser, tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "xdg"))
    monkeypatch.setenv("UMLBOT_LAYOUT_CACHE", "user")  # not the shipped file: ELK lays out first
    errors: list[str] = []
    with studio(["studio", str(CAR_MODEL), "--port", "0"], tmp_path) as proc:
        first = open_page(browser, proc.url, errors)
        lanes = lanes_of(CAR_MODEL)
        assert lanes >= 3
        # the first open: ELK laid out every lane of every diagram and the server kept each layout
        first.wait_for_function("(n) => window.__studio.layouts.kept === n", arg=lanes)
        assert layouts(first) == {"elk": lanes, "cached": 0, "kept": lanes, "unfit": 0}
        drawn: dict[str, Any] = first.evaluate(DRAWN_JS, "activity-main")
        first.context.close()
        kept = list((tmp_path / "xdg" / "umlbot" / "layouts").glob("*.json"))
        assert len(kept) == lanes, kept

        second = open_page(browser, proc.url, errors)
        second.wait_for_function("(n) => window.__studio.layouts.cached === n", arg=lanes)
        assert layouts(second) == {"elk": 0, "cached": lanes, "kept": 0, "unfit": 0}
        again: dict[str, Any] = second.evaluate(DRAWN_JS, "activity-main")
        # ELK's warm-up in the background lays a cached lane out again: the same as the cache
        second.wait_for_function("window.__studio.layouts.warmed === 1")
        assert second.evaluate("window.__studio.layouts.differ") == 0
        # main's opening view (its two big branches collapsed into boxes: docs/studio.md, Regions)
        assert sum(k.startswith("node ") for k in drawn) >= 60
        assert sum(k.startswith("flow ") for k in drawn) >= 75
        assert again == drawn  # every node at its place, every flow on its path
        second.context.close()

        # an entry that is not a layout any more is ELK again, and the same drawing
        for path in kept:
            path.write_text("{broken", encoding="utf-8")
        third = open_page(browser, proc.url, errors)
        third.wait_for_function("(n) => window.__studio.layouts.elk === n", arg=lanes)
        assert layouts(third)["cached"] == 0
        assert third.evaluate(DRAWN_JS, "activity-main") == drawn
        third.wait_for_function("(n) => window.__studio.layouts.kept === n", arg=lanes)
        third.context.close()

        # an entry that fits its graph but is not what ELK gives (moved by hand): drawn as kept,
        # found out by the warm-up, and replaced with ELK's for the next open
        main_key = max(kept, key=lambda p: p.stat().st_size)  # `main`'s one big lane
        entry = json.loads(main_key.read_text(encoding="utf-8"))
        for child in entry["layout"]["children"]:
            child["x"] += 7
        main_key.write_text(json.dumps(entry), encoding="utf-8")
        fourth = open_page(browser, proc.url, errors)
        assert fourth.evaluate(DRAWN_JS, "activity-main") != drawn
        fourth.wait_for_function("window.__studio.layouts.warmed === 1")
        assert fourth.evaluate("window.__studio.layouts.differ") == 1
        fourth.wait_for_function("window.__studio.layouts.kept === 1")
        fourth.context.close()
        fifth = open_page(browser, proc.url, errors)
        assert fifth.evaluate(DRAWN_JS, "activity-main") == drawn
        assert layouts(fifth)["elk"] == 0
        fifth.context.close()
    assert "layout cache: a bad entry is ignored" in proc.log_text()
    assert errors == [], errors


@pytest.mark.parametrize("model", [CAR_MODEL, STEREO_MODEL], ids=lambda m: m.name)
def test_the_layouts_shipped_beside_a_reference_model_are_todays(
        browser: Browser, tmp_path: Path, monkeypatch: pytest.MonkeyPatch, model: Path) -> None:
    """What the page gives ELK for each lane of each activity diagram is in the shipped file: a
    change of the layout code, of ELK, of a node's size or of the model makes this fail (refresh
    with `make layout-cache`)."""
    shipped = read_shipped(model / SHIPPED_NAME)
    assert shipped, f"{model / SHIPPED_NAME} holds no layouts"
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "xdg"))  # an empty user cache: a fresh clone
    monkeypatch.delenv("UMLBOT_LAYOUT_CACHE", raising=False)
    errors: list[str] = []
    with studio(["studio", str(model), "--port", "0"], tmp_path) as proc:
        page = open_page(browser, proc.url, errors)
        lanes = lanes_of(model)
        # every diagram is laid out after the first one, in the background
        page.wait_for_function("(n) => window.__studio.layouts.elk + window.__studio.layouts.cached === n",
                               arg=lanes)
        stats = layouts(page)
        assert stats["elk"] == 0, (f"{stats['elk']} lanes of {model.name} laid out by ELK: "
                                   f"{model / SHIPPED_NAME} is stale; run `make layout-cache`", stats)
        assert stats["cached"] == lanes == len(shipped), (stats, lanes, len(shipped))
        page.context.close()
    assert errors == [], errors
