"""A page the studio drops for falling behind, in a real browser (Debian's Chromium): it says why,
reconnects and starts again from a fresh hello and snapshot, and then follows the robot again."""

from __future__ import annotations

from playwright.sync_api import expect
from robot_run import CAR_MODEL
from studio_support import chromium
from test_studio_hub import ROBOT, on_loop, push_until_dropped, served, trace_event

from umlbot.studio.hub import CLOSE_TOO_SLOW, Hub
from umlbot.studio.sources import studio_data

WAIT_MS = 30_000


def test_a_page_that_fell_behind_says_so_reconnects_and_resyncs() -> None:
    hub = Hub(keep_trace=1000)  # the snapshot of the page that comes back stays small
    limit = 256 * 1024
    data = studio_data(CAR_MODEL, ROBOT)
    with served(hub, page_limit=limit, data=data) as thread, chromium() as browser:
        page = browser.new_page(viewport={"width": 1400, "height": 900})
        page.goto(thread.url)
        page.wait_for_function("window.__studio && window.__studio.ready === true", timeout=WAIT_MS)
        assert page.evaluate("window.__studio.hellos") == 1
        # the page's own code keeps its main thread busy for 8 s: Chromium stops reading the socket
        # once its buffers are full, and the robot goes on talking (4 KB events, ~60 MB/s offered)
        page.evaluate("setTimeout(() => { const t = Date.now(); while (Date.now() - t < 8000); }, 0)")
        pushed = push_until_dropped(hub, thread, detail_chars=4000)
        conn = page.locator("#connection")
        expect(conn).to_have_attribute("data-close-code", str(CLOSE_TOO_SLOW), timeout=WAIT_MS)
        # it starts again from a second hello, and follows the robot as before
        page.wait_for_function("window.__studio.hellos === 2", timeout=WAIT_MS)
        expect(conn).to_have_attribute("data-state", "open", timeout=WAIT_MS)
        for j in range(3):
            hub.push({**trace_event(pushed + j), "node": "forward"})
        expect(page.locator('g.node[data-lane="RaspberryPI"][data-node="forward"]')).to_have_attribute(
            "data-count", "3", timeout=WAIT_MS)
        assert on_loop(thread, lambda: len(hub.pages)) == 1 and hub.dropped_pages == 1
