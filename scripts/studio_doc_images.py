"""The screenshots of docs/studio.md's tutorial, "Your first robot without writing YAML", taken by
doing what it says in a real `umlbot studio` and Debian's Chromium (Playwright).

    .venv/bin/python scripts/studio_doc_images.py [--out docs/images]   (make doc-images)

In a new temporary folder, `umlbot studio my_robot` (the folder does not exist yet, so the header
shows `my_robot` as a user's would): the starter form (studio-edit-new.png), the component library
and LeftActuator's deployment (studio-edit-components.png), the new Stop lane's nodes and their
problems (studio-edit-problems.png), the call editor's completion and argument hint in the main
lane (studio-edit-completion.png), and the saved robot running on the corridor
(studio-edit-run.png). Exit 1, naming the step, when the page does not do what the tutorial says.
"""

from __future__ import annotations

import argparse
import itertools
import sys
import tempfile
from pathlib import Path

REPO = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(REPO / "tests"))

from conftest import BrokerProcess, free_port  # noqa: E402
from playwright.sync_api import Browser, Page, expect  # noqa: E402
from studio_support import chromium, studio  # noqa: E402
from test_studio_edit_browser import (  # noqa: E402
    click_kind,
    click_node,
    connect,
    drag_kind_onto_lane,
    selected_node,
    settled,
    show,
    type_call,
)

#: the window of the tutorial's screenshots
WIDTH, HEIGHT = 1600, 1000
#: the main lane's calls (step 5), in order
DRIVE = ["LeftActuator.dutycycle(60)", "RightActuator.dutycycle(60)", "LeftActuator.enabled(true)",
         "RightActuator.enabled(true)", "msleep(1500)", "Stop"]


def step(text: str) -> None:
    print(f"studio_doc_images: {text}", flush=True)


def starter(page: Page, out: Path) -> None:
    step("1. the starter model")
    expect(page.locator("#new-model-form")).to_be_visible()
    expect(page.locator('#new-model-form [name="model-name"]')).to_have_value("my_robot")
    expect(page.locator('#palette [data-impl="l298n"]')).to_be_visible()  # the library, to browse
    expect(page.locator("#broker-status")).to_have_attribute("data-state", "connected")
    page.screenshot(path=str(out / "studio-edit-new.png"))
    page.locator("#new-model").click()
    expect(page.locator('#diagram-list [data-diagram="components"]')).to_be_visible()
    settled(page)


def components(page: Page, out: Path) -> None:
    step("2. the components")
    show(page, "components")
    expect(page.locator('#palette [data-impl="l298n"]')).to_contain_text("dutycycle")
    page.locator('g.component[data-component="LeftActuator"]').click()
    expect(page.locator('#props [name="setting-in1"]')).to_have_value("22")
    expect(page.locator("#broker-status")).to_have_attribute("data-state", "connected")
    page.wait_for_timeout(300)
    page.screenshot(path=str(out / "studio-edit-components.png"))


def stop_lane(page: Page, out: Path) -> None:
    step("3. a Stop swimlane")
    show(page, "activity-main")
    page.locator('#palette [name="lane-name"]').fill("Stop")
    page.locator('#palette [data-action="add-lane"]').click()
    settled(page)
    expect(page.locator('svg.diagram g.lane[data-lane="Stop"]')).to_be_visible()
    drag_kind_onto_lane(page, "fork", "Stop")
    fork = selected_node(page)
    click_kind(page, "action")
    left = selected_node(page)
    click_kind(page, "action")
    right = selected_node(page)
    click_kind(page, "join")
    join = selected_node(page)
    expect(page.locator("#diagnostics li.error").first).to_be_visible()
    page.wait_for_timeout(300)
    page.screenshot(path=str(out / "studio-edit-problems.png"))
    step("4. connect and fill in")
    for source, target in (("start", fork), (fork, left), (fork, right), (left, join), (right, join),
                           (join, "end")):
        connect(page, "Stop", source, target)
    type_call(page, "Stop", left, "LeftActuator", "enabled", "false")
    type_call(page, "Stop", right, "RightActuator", "enabled", "false")
    expect(page.locator('svg.diagram g.node.error[data-lane="Stop"]')).to_have_count(0)


def main_lane(page: Page, out: Path) -> None:
    step("5. the main lane")
    show(page, "activity-main")
    lane = "RaspberryPI"
    page.locator(f'svg.diagram g.lane[data-lane="{lane}"] .lane-title').first.click()
    actions = []
    for _ in DRIVE:
        click_kind(page, "action")
        actions.append(selected_node(page))
    chain = ["start", *actions, "end"]
    for source, target in itertools.pairwise(chain):
        connect(page, lane, source, target)
    # the first call typed with the completion: the argument hint shows the allowed range
    click_node(page, lane, actions[0])
    call = page.locator('#props input[name="call"]')
    call.click()
    call.press_sequentially("LeftActuator.dutycycle(", delay=30)
    expect(page.locator("#props .signature")).to_contain_text("0..100")
    expect(page.locator("#props .completions li").first).to_be_visible()
    page.wait_for_timeout(300)
    page.screenshot(path=str(out / "studio-edit-completion.png"))
    call.press_sequentially("60)", delay=30)
    call.press("Escape")
    call.press("Enter")
    settled(page)
    for node_id, text in zip(actions[1:], DRIVE[1:], strict=True):
        click_node(page, lane, node_id)
        field = page.locator('#props input[name="call"]')
        field.fill(text)
        field.press("Enter")
        settled(page)
    expect(page.locator("#diagnostics li.error")).to_have_count(0)


def save_and_run(page: Page, out: Path, folder: Path) -> None:
    step("6. save and run")
    page.keyboard.press("Control+s")
    expect(page.locator("#save")).to_have_attribute("data-dirty", "false")
    assert (folder / "activities" / "stop.yaml").is_file(), "Save wrote no activities/stop.yaml"
    page.locator("#track").select_option("corridor")
    page.locator("#run-speed").select_option("0.5")  # the 1.5 s drive lasts 3 s: time to see it
    page.locator("#run").click()
    # while the car drives: the msleep node is the one running, the toolbar shows the run's broker
    sleeping = """() => {
      const status = document.querySelector('#broker-status');
      return status?.dataset.source === 'run' && status?.dataset.state === 'connected'
        && [...document.querySelectorAll('svg.diagram g.node.running')]
          .some((g) => g.querySelector('text.label')?.textContent === 'msleep(1500)');
    }"""
    page.wait_for_function(sleeping, timeout=60_000)
    page.wait_for_timeout(1000)  # the car on its way
    assert page.evaluate(sleeping), "the drive ended before its screenshot"
    page.locator("#diagram-list").click(position={"x": 5, "y": 5})  # no hover outline
    page.screenshot(path=str(out / "studio-edit-run.png"))
    expect(page.locator('#notice[data-kind="run-ended"], #notice[data-kind="run-goal"]')).to_be_visible(
        timeout=60_000)


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--out", type=Path, default=REPO / "docs" / "images",
                        help="where the screenshots go (default: docs/images)")
    args = parser.parse_args()
    out: Path = args.out.resolve()
    out.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory(prefix="umlbot-doc-images-") as tmp, chromium() as browser:
        work = Path(tmp)
        # the robot's broker (a Mosquitto of its own, as `make test` starts them): "broker connected"
        broker = BrokerProcess("mosquitto", free_port(), work)
        broker.start()
        try:
            return shoot(browser, work, broker.url, out)
        finally:
            broker.stop()


def shoot(browser: Browser, work: Path, broker_url: str, out: Path) -> int:
    """The tutorial in `work`, its screenshots into `out`; 1 when the page reported an error."""
    errors: list[str] = []
    with studio(["studio", "--new", "my_robot", "--port", "0"], work, broker_url=broker_url) as proc:
        page = browser.new_page(viewport={"width": WIDTH, "height": HEIGHT})
        page.on("pageerror", lambda exc: errors.append(str(exc)))
        page.goto(proc.url)
        page.set_default_timeout(30_000)
        page.wait_for_function("window.__studio && window.__studio.ready === true && !!window.__studio.edit")
        starter(page, out)
        components(page, out)
        stop_lane(page, out)
        main_lane(page, out)
        save_and_run(page, out, work / "my_robot")
        page.close()
    if errors:
        print(f"studio_doc_images: the page failed: {errors}", file=sys.stderr)
        return 1
    step(f"done: {out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
