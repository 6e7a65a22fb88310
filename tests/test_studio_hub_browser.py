"""A page the studio drops for falling behind, in a real browser (Debian's Chromium): it says why,
reconnects and starts again from a fresh hello and snapshot, and then follows the robot again."""

from __future__ import annotations

import time

from playwright.sync_api import expect
from robot_run import CAR_MODEL
from studio_support import chromium
from test_studio_hub import ROBOT, on_loop, served, trace_event

from umlbot.studio.hub import CLOSE_TOO_SLOW, Hub
from umlbot.studio.sources import studio_data

WAIT_MS = 30_000


def test_a_page_that_fell_behind_says_so_reconnects_and_resyncs() -> None:
    hub = Hub()
    limit = 256 * 1024
    data = studio_data(CAR_MODEL, ROBOT)
    with served(hub, page_limit=limit, data=data) as thread, chromium() as browser:
        page = browser.new_page(viewport={"width": 1400, "height": 900})
        page.goto(thread.url)
        page.wait_for_function("window.__studio && window.__studio.ready === true", timeout=WAIT_MS)
        assert page.evaluate("window.__studio.hellos") == 1
        # the page's own code keeps its main thread busy for 4 s: Chromium stops reading the socket
        # meanwhile, and the robot goes on talking
        page.evaluate("setTimeout(() => { const t = Date.now(); while (Date.now() - t < 4000); }, 0)")
        i = 0
        while on_loop(thread, lambda: hub.dropped_pages) == 0:
            for _ in range(300):
                hub.push(trace_event(i))
                i += 1
            time.sleep(0.02)
            assert i < 300_000, "the busy page was never dropped"
        conn = page.locator("#connection")
        expect(conn).to_have_attribute("data-close-code", str(CLOSE_TOO_SLOW), timeout=WAIT_MS)
        # it starts again from a second hello, and follows the robot as before
        page.wait_for_function("window.__studio.hellos === 2", timeout=WAIT_MS)
        expect(conn).to_have_attribute("data-state", "open", timeout=WAIT_MS)
        for j in range(3):
            hub.push({**trace_event(i + j), "node": "forward"})
        expect(page.locator('g.node[data-lane="RaspberryPI"][data-node="forward"]')).to_have_attribute(
            "data-count", "3", timeout=WAIT_MS)
        assert on_loop(thread, lambda: len(hub.pages)) == 1 and hub.dropped_pages == 1
