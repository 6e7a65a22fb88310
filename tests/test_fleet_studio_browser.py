"""The studio's fleet view in a real browser (Debian's Chromium): `umlbot studio MODEL --broker HUB
--fleet` lists every car of a fleet on one machine (each on its own leaf Mosquitto bridged to the
hub) with its orchestrator's state, running nodes, faults and components; a click follows a car
in the diagrams; it says when the hub is unreachable, and shows the cars again once it is back."""

from __future__ import annotations

from pathlib import Path

from playwright.sync_api import expect
from robot_run import CAR_MODEL
from studio_support import chromium, shot, studio

from umlbot.fleet import SimFleet

WAIT_MS = 30_000
#: slow enough that the cars are still driving while the test looks (s_bend: ~28 s of sim time)
CAR_ARGS = ["--track", "s_bend", "--speed", "0.5", "--timeout", "300"]


def test_fleet_view_lists_the_cars_follows_one_and_says_when_the_hub_is_gone(tmp_path: Path) -> None:
    with SimFleet(CAR_MODEL / "model.yaml", ["car1", "car2"], CAR_ARGS, workdir=tmp_path) as fleet, \
            studio(["studio", str(CAR_MODEL), "--broker", fleet.hub_url, "--fleet", "--port", "0"],
                   tmp_path) as proc, chromium() as browser:
        page = browser.new_page(viewport={"width": 1400, "height": 900})
        page.goto(proc.url)
        rows = page.locator("#fleet-robots tbody tr")
        expect(rows).to_have_count(2, timeout=WAIT_MS)
        hub = page.locator("#fleet .hub")
        expect(hub).to_have_text(f"hub {fleet.hub_url}: 2 robots", timeout=WAIT_MS)
        for robot in ("car1", "car2"):
            row = page.locator(f'#fleet-robots tr[data-robot="{robot}"]')
            expect(row.locator("td.state")).to_have_text("running", timeout=WAIT_MS)
            expect(row.locator("td.components")).to_have_text("5/5 online", timeout=WAIT_MS)
            expect(row.locator("td.faults")).to_have_text("none")
            expect(row.locator("td.running")).to_contain_text(":", timeout=WAIT_MS)  # "<lane>: <node>"
        # follow car2: its nodes light up in the diagram, its name is in the title
        car2 = page.locator('#fleet-robots tr[data-robot="car2"]')
        car2.click()
        expect(car2).to_have_attribute("data-followed", "true", timeout=WAIT_MS)
        expect(page.locator("#title")).to_contain_text("car2", timeout=WAIT_MS)
        expect(page.locator("#orchestrator-status")).to_contain_text("running", timeout=WAIT_MS)
        expect(page.locator("g.node[data-count]").first).to_be_visible(timeout=WAIT_MS)
        shot(page, "fleet-view.png")
        # the hub goes away: the view says so and keeps what it saw
        fleet.fleet.hub.kill()
        expect(hub).to_have_attribute("data-connected", "false", timeout=WAIT_MS)
        expect(hub).to_contain_text("unreachable", timeout=WAIT_MS)
        expect(rows).to_have_count(2)
        shot(page, "fleet-view-hub-down.png")
        # the hub is back: connected again, both cars still running (the bridges re-send their state)
        fleet.fleet.hub.start()
        expect(hub).to_have_attribute("data-connected", "true", timeout=WAIT_MS)
        for robot in ("car1", "car2"):
            row = page.locator(f'#fleet-robots tr[data-robot="{robot}"]')
            expect(row.locator("td.state")).to_have_text("running", timeout=WAIT_MS)
        assert all(car.poll() is None for car in fleet.cars.values()), "a car stopped"
