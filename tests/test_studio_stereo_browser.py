"""The studio's sim panel shows the stereo camera's depth picture beside the track (real Chromium),
following `umlbot sim models/stereo_car --studio`; a screenshot in out/studio-stereo.png."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import pytest
from playwright.sync_api import Browser, expect
from studio_support import StudioProc, chromium, shot

REPO = Path(__file__).resolve().parent.parent
WAIT_MS = 30_000


@pytest.fixture(scope="module")
def browser() -> Iterator[Browser]:
    with chromium() as launched:
        yield launched


def test_the_sim_panel_shows_the_cameras_depth_picture(browser: Browser, tmp_path: Path) -> None:
    track = REPO / "models" / "tracks" / "room_exit.yaml"  # long: the car still drives when the page opens
    proc = StudioProc(["sim", str(REPO / "models" / "stereo_car"), "--track", str(track), "--port", "0",
                       "--speed", "1", "--timeout", "120", "--studio", "--studio-port", "0"], tmp_path)
    try:
        page = browser.new_page(viewport={"width": 1600, "height": 1000})
        errors: list[str] = []
        page.on("pageerror", lambda exc: errors.append(str(exc)))
        page.goto(proc.url)
        page.set_default_timeout(WAIT_MS)
        page.wait_for_function("window.__studio && window.__studio.ready === true")
        expect(page.locator("#sim svg")).to_be_visible()
        depth = page.locator("#sim-depth")
        expect(depth).to_be_visible()
        expect(depth).to_have_attribute("data-component", "Eye")
        expect(depth.locator("figcaption")).to_contain_text("Eye · depth")
        # a new picture as the car moves on, drawn with something near (bright) in it
        page.wait_for_function("Number(document.querySelector('#sim-depth').dataset.frames) >= 2")
        bright = page.evaluate("""() => {
            const c = document.querySelector('#sim-depth canvas');
            const d = c.getContext('2d').getImageData(0, 0, c.width, c.height).data;
            let n = 0;
            for (let i = 0; i < d.length; i += 4) if (d[i] > 40 && d[i] === d[i + 2]) n++;
            return n;
        }""")
        assert bright > 0
        box = depth.bounding_box()
        track_box = page.locator("#sim svg").bounding_box()
        assert box is not None and track_box is not None
        assert box["x"] >= track_box["x"] + track_box["width"] - 1, "beside the track, to its right"
        assert errors == [], errors
        shot(page, "studio-stereo.png")
        page.close()
    finally:
        proc.stop()
