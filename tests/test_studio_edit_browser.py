"""umlbot studio as an editor, in a real browser (Debian's Chromium driven by Playwright).

From an empty folder, the reference car's "Stop" swimlane (models/robot_car/activities/motion.yaml)
is built by clicking and typing only: start -> fork -> LeftActuator.enabled(false) and
RightActuator.enabled(false) -> join -> end. After Save the folder passes `umlbot check`. The rest
of the car (the other swimlanes) is then copied into the folder *through the file system* while the
page is open — the page reloads it with a notice — and `umlbot sim` drives the car to the goal.
A bad guard shows the checker's own message on its node and Undo removes it; a file changed on
disk while the page has unsaved edits raises a notice and overwrites nothing. Screenshots under out/.
"""

from __future__ import annotations

import json
import re
import shutil
import subprocess
from collections.abc import Iterator
from pathlib import Path

import pytest
from playwright.sync_api import Browser, Page, Route, expect
from robot_run import CAR_MODEL, umlbot_argv
from studio_support import chromium, shot, studio

REPO = Path(__file__).resolve().parent.parent
WAIT_MS = 30_000
TRACK = REPO / "models" / "tracks" / "corridor.yaml"


@pytest.fixture(scope="module")
def browser() -> Iterator[Browser]:
    with chromium() as launched:
        yield launched


def open_page(browser: Browser, url: str, errors: list[str]) -> Page:
    page = browser.new_page(viewport={"width": 1600, "height": 1000})
    page.on("pageerror", lambda exc: errors.append(str(exc)))
    page.goto(url)
    page.set_default_timeout(WAIT_MS)
    page.wait_for_function("window.__studio && window.__studio.ready === true && !!window.__studio.edit")
    return page


def settled(page: Page) -> None:
    """Every edit the page sent has been answered and drawn."""
    page.wait_for_function("window.__studio.edit.busy === false")
    page.wait_for_function("window.__studio.ready === true")


def show(page: Page, diagram: str) -> None:
    page.locator(f'#diagram-list [data-diagram="{diagram}"]').click()
    expect(page.locator(f'svg[data-diagram="{diagram}"]')).to_be_visible()


def node(page: Page, lane: str, node_id: str) -> str:
    return f'svg.diagram g.node[data-lane="{lane}"][data-node="{node_id}"]'


def click_node(page: Page, lane: str, node_id: str) -> None:
    page.locator(node(page, lane, node_id)).click()


def set_value(page: Page, lane: str, node_id: str, value: str) -> None:
    """Type a new value into a node's `value` field and send it (Enter)."""
    click_node(page, lane, node_id)
    field = page.locator('#props input[name="value"]')
    field.fill(value)
    field.press("Enter")
    settled(page)


def drag_kind_onto_lane(page: Page, kind: str, lane: str) -> None:
    """Drag a node kind from the palette and drop it on the swimlane."""
    item = page.locator(f'#palette [data-kind="{kind}"]').bounding_box()
    target = page.locator(f'svg.diagram g.lane[data-lane="{lane}"] rect.lane-bg').bounding_box()
    assert item and target
    page.mouse.move(item["x"] + item["width"] / 2, item["y"] + item["height"] / 2)
    page.mouse.down()
    page.mouse.move(target["x"] + target["width"] / 2, target["y"] + target["height"] - 30, steps=8)
    page.mouse.up()
    settled(page)


def click_kind(page: Page, kind: str) -> None:
    """Click a node kind in the palette: it is added to the selected swimlane."""
    page.locator(f'#palette [data-kind="{kind}"]').click()
    settled(page)


def selected_node(page: Page) -> str:
    """The id of the node the properties panel shows (a new node is selected)."""
    return str(page.locator("svg.diagram g.node.selected").get_attribute("data-node"))


def connect(page: Page, lane: str, source: str, target: str) -> None:
    click_node(page, lane, source)
    page.locator('#props [name="connect"]').click()
    click_node(page, lane, target)
    settled(page)
    edge = f'svg.diagram g.edge[data-lane="{lane}"][data-source="{source}"][data-target="{target}"]'
    expect(page.locator(edge)).to_have_count(1)


def type_call(page: Page, lane: str, node_id: str, component: str, feature: str, args: str) -> None:
    """Type `Component.feature(args)` into the action's call editor, picking the completions."""
    click_node(page, lane, node_id)
    call = page.locator('#props input[name="call"]')
    call.click()
    call.press_sequentially(component[:4], delay=20)
    option = page.locator(f'#props .completions li[data-label="{component}"]')
    expect(option).to_be_visible()
    option.click()  # picks the component with the mouse
    if not call.input_value().endswith("."):
        call.press_sequentially(".", delay=20)
    feat = page.locator(f'#props .completions li[data-label="{feature}"]')
    expect(feat).to_be_visible()
    while page.locator("#props .completions li.active").get_attribute("data-label") != feature:
        call.press("ArrowDown")
    call.press("Tab")  # picks the feature with the keyboard
    if not call.input_value().endswith("("):
        call.press_sequentially("(", delay=20)
    # the argument hint names the parameter (with its allowed range when it has one)
    expect(page.locator("#props .signature")).to_be_visible()
    expect(page.locator("#props .signature")).to_contain_text(feature)
    call.press_sequentially(args + ")", delay=20)
    call.press("Enter")
    settled(page)
    expect(page.locator(node(page, lane, node_id)).locator("text.label")).to_have_text(
        f"{component}.{feature}({args})")


def check_lines(folder: Path, cwd: Path) -> tuple[int, list[str]]:
    done = subprocess.run(umlbot_argv("check", str(folder)), capture_output=True, text=True,
                          timeout=120, check=False, cwd=cwd)
    printed = (done.stdout + done.stderr).splitlines()
    lines = [line for line in printed if re.search(r": (error|warning): ", line)]
    return done.returncode, lines


def test_build_the_stop_lane_from_an_empty_folder_save_check_and_sim(
    browser: Browser, tmp_path: Path
) -> None:
    folder = tmp_path / "models" / "my_robot"  # does not exist yet: the studio offers a starter model
    folder.parent.mkdir()
    errors: list[str] = []
    with studio(["studio", "--new", str(folder), "--port", "0"], tmp_path) as proc:
        page = open_page(browser, proc.url, errors)
        form = page.locator("#new-model-form")
        expect(form).to_be_visible()
        shot(page, "studio-edit-empty.png")
        form.locator('[name="model-name"]').fill("car")
        page.locator("#new-model").click()
        expect(page.locator('#diagram-list [data-diagram="components"]')).to_be_visible()
        settled(page)
        assert (folder / "model.yaml").is_file()  # the starter model is written at once

        # the component diagram's palette is the component library (kinds, implementations, seeds)
        show(page, "components")
        expect(page.locator('#palette [data-impl="l298n"]')).to_contain_text("enabled")
        shot(page, "studio-edit-components.png")

        # a virtual swimlane "Stop" in its own file
        show(page, "activity-main")
        page.locator('#palette [name="lane-name"]').fill("Stop")
        page.locator('#palette [data-action="add-lane"]').click()
        settled(page)
        lane = page.locator('svg.diagram g.lane[data-lane="Stop"]')
        expect(lane).to_be_visible()
        start = lane.locator('g.node[data-kind="start"]')
        expect(start).to_have_count(1)
        start_id = str(start.get_attribute("data-node"))
        # a new lane is start -> end
        end = str(lane.locator('g.node[data-kind="end"]').get_attribute("data-node"))

        drag_kind_onto_lane(page, "fork", "Stop")  # dragged from the palette
        fork = selected_node(page)
        click_kind(page, "action")  # clicked: added to the selected node's lane
        left = selected_node(page)
        click_kind(page, "action")
        right = selected_node(page)
        click_kind(page, "join")
        join = selected_node(page)
        assert len({fork, left, right, join, end}) == 5

        connect(page, "Stop", start_id, fork)
        connect(page, "Stop", fork, left)
        connect(page, "Stop", fork, right)
        connect(page, "Stop", left, join)
        connect(page, "Stop", right, join)
        connect(page, "Stop", join, end)
        type_call(page, "Stop", left, "LeftActuator", "enabled", "false")
        type_call(page, "Stop", right, "RightActuator", "enabled", "false")
        expect(page.locator("#save")).to_have_attribute("data-dirty", "true")
        shot(page, "studio-edit-stop.png")

        page.keyboard.press("Control+s")
        expect(page.locator("#save")).to_have_attribute("data-dirty", "false")
        written = (folder / "activities" / "stop.yaml").read_text(encoding="utf-8")
        assert "LeftActuator.enabled(false)" in written and "RightActuator.enabled(false)" in written
        code, lines = check_lines(folder, tmp_path)
        assert code == 0, lines

        # The rest of the car: the reference lanes other than Stop, copied into the folder through the
        # file system while the page is open (it reloads them and says so).
        motion = (CAR_MODEL / "activities" / "motion.yaml").read_text(encoding="utf-8")
        others = motion[: motion.index("  - lane: Stop")]
        (folder / "activities" / "motion.yaml").write_text(others, encoding="utf-8")
        for name in ("main.yaml", "measure.yaml"):
            shutil.copyfile(CAR_MODEL / "activities" / name, folder / "activities" / name)
        expect(page.locator('#notice[data-kind="reloaded"]')).to_be_visible()
        expect(page.locator('#diagram-list [data-diagram="activity-motion"]')).to_be_visible()
        code, lines = check_lines(folder, tmp_path)
        assert code == 0, lines

        sim = subprocess.run(umlbot_argv("sim", str(folder), "--track", str(TRACK), "--port", "0",
                                         "--speed", "4", "--timeout", "120", "--json"),
                             capture_output=True, text=True, timeout=300, check=False, cwd=tmp_path)
        summary = json.loads(sim.stdout.strip().splitlines()[-1])
        assert sim.returncode == 0 and summary["goal"], (summary, sim.stderr[-2000:])
        assert errors == [], errors
        page.close()


def complete_car(folder: Path) -> None:
    shutil.copytree(CAR_MODEL, folder)


def test_a_model_created_in_the_page_is_followed_under_its_own_name(browser: Browser, tmp_path: Path) -> None:
    errors: list[str] = []
    with studio(["studio", "--new", str(tmp_path / "newbot"), "--port", "0"], tmp_path) as proc:
        page = open_page(browser, proc.url, errors)
        # nothing named yet: no robot name is made up, and there is nothing to undo, save or run
        expect(page.locator("#title")).to_have_text("new model")
        expect(page.locator("#edit-tools")).to_be_hidden()
        expect(page.locator("#diagnostics li")).to_have_count(0)
        assert "robot car" not in proc.lines[-1], proc.lines
        # a name that is no plain name is refused at the field; the fixed one clears it
        name = page.locator('#new-model-form [name="model-name"]')
        name.fill("Robbie the car")
        page.locator("#new-model").click()
        expect(page.locator('#new-model-form .field-error[data-field="name"]')).to_contain_text("plain name")
        expect(name).to_have_attribute("aria-invalid", "true")
        expect(page.locator("#notice")).to_be_hidden()
        shot(page, "studio-edit-new-bad-name.png")
        name.fill("mybot")
        page.locator("#new-model").click()
        expect(page.locator("#title")).to_have_text("mybot · robot mybot")
        expect(page.locator("#edit-tools")).to_be_visible()
        expect(page.locator(".field-error")).to_have_count(0)
        # an error notice goes once a later request succeeds
        assert page.evaluate("window.__studio.edit.send([{op: 'remove_lane', lane: 'Nope'}])") is False
        expect(page.locator('#notice[data-kind="error"]')).to_contain_text("no swimlane 'Nope'")
        expect(page.locator('#notice[data-kind="error"]')).not_to_contain_text("operation 1")
        show(page, "activity-main")
        page.locator('#palette [name="lane-name"]').fill("Wait")
        page.locator('#palette [data-action="add-lane"]').click()
        settled(page)
        expect(page.locator('#notice[data-kind="error"]')).to_be_hidden()
        page.reload()
        page.wait_for_function("window.__studio && window.__studio.ready === true")
        expect(page.locator("#title")).to_have_text("mybot · robot mybot")
        page.close()
    assert errors == [], errors


def test_a_decisions_second_output_asks_for_its_guard_instead_of_making_one_up(
        browser: Browser, tmp_path: Path) -> None:
    folder = tmp_path / "bot"
    errors: list[str] = []
    with studio(["studio", "--new", str(folder), "--port", "0"], tmp_path) as proc:
        page = open_page(browser, proc.url, errors)
        page.locator('#new-model-form [name="model-name"]').fill("bot")
        page.locator("#new-model").click()
        settled(page)
        show(page, "activity-main")
        click_node(page, "RaspberryPI", "start")
        click_kind(page, "decision")  # dropped after the selected start, wired in: its else is the end
        decision = selected_node(page)
        else_edge = f'svg.diagram g.edge[data-source="{decision}"][data-target="end"] text.elabel'
        expect(page.locator(else_edge)).to_have_text("else")  # the first output is shown as the else
        click_kind(page, "action")
        action = selected_node(page)
        connect(page, "RaspberryPI", decision, action)  # the second output: it needs a guard
        guard = page.locator(f'#props input[name="guard"][data-target="{action}"]')
        expect(guard).to_have_value("")
        expect(guard).to_be_focused()
        assert guard.get_attribute("placeholder")
        edge = f'svg.diagram g.edge[data-source="{decision}"][data-target="{action}"] text.elabel'
        expect(page.locator(edge)).to_have_text("?")
        on_node = page.locator(node(page, "RaspberryPI", decision))
        expect(on_node).to_have_class(re.compile(r"(^|\s)error(\s|$)"))
        assert "decision output without guard" in (on_node.get_attribute("data-message") or "")
        guard.fill("Application.exit")
        guard.press("Enter")
        settled(page)
        expect(page.locator(node(page, "RaspberryPI", decision))).not_to_have_class(
            re.compile(r"(^|\s)error(\s|$)"))
        page.keyboard.press("Control+s")
        page.wait_for_function("window.__studio.edit.dirty === false")
        page.close()
    text = (folder / "activities" / "main.yaml").read_text(encoding="utf-8")
    assert f"branches: [{{if: Application.exit, then: {action}}}, {{else: end}}]" in text, text
    assert errors == [], errors


def test_completions_answered_late_for_older_text_do_not_rewrite_what_was_typed(
        browser: Browser, tmp_path: Path) -> None:
    # The completion asked for when the guard field got focus (empty text) is held back until
    # the user has typed the whole guard; its late answer must not be taken for the typed text
    # (it once was, and Enter then spliced the first completion in front of the guard).
    folder = tmp_path / "bot"
    errors: list[str] = []
    with studio(["studio", "--new", str(folder), "--port", "0"], tmp_path) as proc:
        page = open_page(browser, proc.url, errors)
        page.locator('#new-model-form [name="model-name"]').fill("bot")
        page.locator("#new-model").click()
        settled(page)
        show(page, "activity-main")
        click_node(page, "RaspberryPI", "start")
        click_kind(page, "decision")  # dropped after the start, wired in: its else is the end
        decision = selected_node(page)
        click_kind(page, "action")
        action = selected_node(page)
        held: list[Route] = []
        page.route("**/api/complete", lambda route: held.append(route))
        connect(page, "RaspberryPI", decision, action)  # the second output focuses its empty guard: asks
        guard = page.locator(f'#props input[name="guard"][data-target="{action}"]')
        expect(guard).to_be_focused()
        for _ in range(50):
            if held:
                break
            page.wait_for_timeout(20)
        assert len(held) == 1, "the focused guard field asks for completions"
        guard.fill("Application.exit")
        held[0].continue_()  # the answer for "" arrives after the text changed
        page.wait_for_timeout(300)
        guard.press("Enter")
        settled(page)
        for route in held[1:]:
            route.continue_()
        page.unroute("**/api/complete")
        expect(guard).to_have_value("Application.exit")
        edge = f'svg.diagram g.edge[data-source="{decision}"][data-target="{action}"] text.elabel'
        expect(page.locator(edge)).to_have_text("Application.exit")
        page.close()
    assert errors == [], errors


def test_a_bad_guard_shows_the_checkers_message_on_its_node_and_undo_removes_it(
    browser: Browser, tmp_path: Path
) -> None:
    folder = tmp_path / "car"
    complete_car(folder)
    errors: list[str] = []
    with studio(["studio", str(folder), "--port", "0"], tmp_path) as proc:
        page = open_page(browser, proc.url, errors)
        show(page, "activity-main")
        page.keyboard.press("f")  # all of it: it opens readable at its top, the loop is further down
        decision = page.locator(node(page, "RaspberryPI", "running"))
        click_node(page, "RaspberryPI", "running")
        guard = page.locator('#props input[name="guard"][data-target="finish"]')
        expect(guard).to_have_value("Application.exit")
        guard.fill("Application.exit >")
        guard.press("Enter")
        settled(page)
        expect(decision).to_have_class(re.compile(r"(^|\s)error(\s|$)"))
        expect(page.locator("#save")).to_have_attribute("data-dirty", "true")
        # exactly what `umlbot check` prints for the same files
        files = page.evaluate("() => fetch('/api/files').then((r) => r.json())")["files"]
        copy = tmp_path / "copy"
        for rel, text in files.items():
            (copy / rel).parent.mkdir(parents=True, exist_ok=True)
            (copy / rel).write_text(text, encoding="utf-8")
        code, lines = check_lines(copy, tmp_path)
        assert code != 0 and lines
        expected = sorted(line.replace(str(copy), str(folder)) for line in lines)
        assert sorted(page.locator("#diagnostics li .text").all_text_contents()) == expected
        assert decision.get_attribute("data-message") in expected
        shot(page, "studio-edit-bad-guard.png")

        page.locator("#undo").click()
        settled(page)
        expect(decision).not_to_have_class(re.compile(r"(^|\s)error(\s|$)"))
        expect(page.locator("#diagnostics li.error")).to_have_count(0)
        click_node(page, "RaspberryPI", "running")
        guard = page.locator('#props input[name="guard"][data-target="finish"]')
        expect(guard).to_have_value("Application.exit")
        page.keyboard.press("Control+Shift+z")  # redo brings it back
        settled(page)
        expect(decision).to_have_class(re.compile(r"(^|\s)error(\s|$)"))
        page.keyboard.press("Control+z")
        settled(page)
        expect(decision).not_to_have_class(re.compile(r"(^|\s)error(\s|$)"))
        # nothing was saved: the file on disk is the reference file
        assert (folder / "activities" / "main.yaml").read_bytes() == (
            CAR_MODEL / "activities" / "main.yaml").read_bytes()
        assert errors == [], errors
        page.close()


def test_a_file_changed_on_disk_while_editing_raises_a_notice_and_nothing_is_lost(
    browser: Browser, tmp_path: Path
) -> None:
    folder = tmp_path / "car"
    complete_car(folder)
    main = folder / "activities" / "main.yaml"
    errors: list[str] = []
    with studio(["studio", str(folder), "--port", "0"], tmp_path) as proc:
        page = open_page(browser, proc.url, errors)
        show(page, "activity-main")
        set_value(page, "RaspberryPI", "set_speed", "55")
        expect(page.locator("#save")).to_have_attribute("data-dirty", "true")

        # someone else edits the same file on disk meanwhile
        theirs = main.read_text(encoding="utf-8").replace("value: 300}", "value: 333}")
        assert "value: 333}" in theirs
        main.write_text(theirs, encoding="utf-8")
        notice = page.locator('#notice[data-kind="conflict"]')
        expect(notice).to_be_visible()
        expect(notice).to_contain_text("activities/main.yaml")
        shot(page, "studio-edit-conflict.png")
        # nothing was overwritten: the disk has their edit, the page still has mine
        assert main.read_text(encoding="utf-8") == theirs
        click_node(page, "RaspberryPI", "set_speed")
        expect(page.locator('#props input[name="value"]')).to_have_value("55")
        expect(page.locator("#save")).to_have_attribute("data-dirty", "true")

        # a plain save is refused while the conflict stands (no silent overwrite)
        page.locator("#save").click()
        expect(page.locator('#notice[data-kind="conflict"]')).to_be_visible()
        assert main.read_text(encoding="utf-8") == theirs

        # "Keep mine" then Save writes my version (the user chose it)
        page.locator('#notice [data-action="keep"]').click()
        page.locator("#save").click()
        expect(page.locator("#save")).to_have_attribute("data-dirty", "false")
        assert "value: 55}" in main.read_text(encoding="utf-8")

        # and "Reload from disk" takes theirs (again: only because the user chose it)
        set_value(page, "RaspberryPI", "set_speed", "60")
        theirs = main.read_text(encoding="utf-8").replace("value: 300}", "value: 310}")
        assert "value: 310}" in theirs
        main.write_text(theirs, encoding="utf-8")
        expect(page.locator('#notice[data-kind="conflict"]')).to_be_visible()
        page.locator('#notice [data-action="reload"]').click()
        expect(page.locator("#save")).to_have_attribute("data-dirty", "false")
        click_node(page, "RaspberryPI", "set_speed")
        expect(page.locator('#props input[name="value"]')).to_have_value("55")
        assert "value: 310}" in main.read_text(encoding="utf-8")
        assert errors == [], errors
        page.close()


def test_run_drives_the_edited_model_in_the_simulator_and_the_page_follows_it(
    browser: Browser, tmp_path: Path
) -> None:
    folder = tmp_path / "car"
    complete_car(folder)
    errors: list[str] = []
    with studio(["studio", str(folder), "--port", "0"], tmp_path) as proc:
        page = open_page(browser, proc.url, errors)
        show(page, "activity-main")
        set_value(page, "RaspberryPI", "set_speed", "80")  # an unsaved edit: Run runs the working copy
        page.locator("#track").select_option("corridor")
        page.locator("#run-speed").select_option("1")
        # Follow turned off by hand (clicking nodes turns it off too) comes back on with Run
        if page.locator("#follow").get_attribute("aria-pressed") == "true":
            page.locator("#follow").click()
        expect(page.locator("#follow")).to_have_attribute("aria-pressed", "false")
        page.locator("#run").click()
        expect(page.locator("#follow")).to_have_attribute("aria-pressed", "true")
        expect(page.locator('#notice[data-kind="run"]')).to_contain_text("corridor at 1\u00d7")
        expect(page.locator("#sim svg")).to_be_visible()
        expect(page.locator('g.node.active[data-lane="RaspberryPI"]')).to_have_count(1)
        speed = page.locator(node(page, "RaspberryPI", "set_speed"))
        expect(speed.locator("text.value")).to_have_text("80")
        page.wait_for_function("document.querySelectorAll('#sim .ping').length > 0")
        shot(page, "studio-edit-run.png")
        page.locator("#stop").click()
        expect(page.locator("#stop")).to_be_disabled()
        expect(page.locator('#notice[data-kind="run-ended"]')).to_be_visible()  # said once, at its end
        # the terminal: one plain line for the run, no log lines of its services and orchestrator
        proc.wait_line("umlbot studio: run on corridor at 1x: stopped from the page (")
        assert [line for line in proc.lines if "run on" in line] == [proc.lines[-1]], proc.lines
        assert not [line for line in proc.log_text().splitlines() if line.startswith("{")], proc.log_text()
        assert (folder / "activities" / "main.yaml").read_bytes() == (
            CAR_MODEL / "activities" / "main.yaml").read_bytes()
        # the orchestrator's status pill carries its whole text as a tooltip (it may be cut short)
        # (waited for: the status moves on from "stopping" to "stopped" meanwhile)
        page.wait_for_function(
            "(() => { const p = document.querySelector('#orchestrator-status');"
            " return !!p && p.title === p.textContent; })()")
        # a reload shows where the run ended, but does not announce its end again
        page.reload()
        page.wait_for_function("window.__studio && window.__studio.ready === true && !!window.__studio.edit")
        expect(page.locator("#sim svg")).to_be_visible()
        page.wait_for_timeout(500)
        expect(page.locator('#notice[data-kind="run-ended"]')).to_be_hidden()
        assert errors == [], errors
        page.close()


def test_the_component_diagram_adds_a_part_from_the_library_with_its_deployment_ports_and_link(
    browser: Browser, tmp_path: Path
) -> None:
    folder = tmp_path / "car"
    complete_car(folder)
    errors: list[str] = []
    with studio(["studio", str(folder), "--port", "0"], tmp_path) as proc:
        page = open_page(browser, proc.url, errors)
        show(page, "components")
        servo = page.locator('#palette [data-impl="servo"]')
        expect(servo.locator('[data-feature="angle"]')).to_contain_text("0..180")  # features with ranges
        servo.click()
        page.locator('#props [name="name"]').fill("Pan")
        # the driver's settings model checks the deployment: the error names the bad setting
        page.locator('#props [name="setting-gpio"]').fill("99")
        page.locator('#props [name="add"]').click()
        settled(page)
        # said at the field, in words, with the schema's range; nothing was sent
        gpio_error = page.locator('#props .field-error[data-field="settings.gpio"]')
        expect(gpio_error).to_have_text("gpio: must be 0..27")
        expect(page.locator('#props [name="setting-gpio"]')).to_have_attribute("aria-invalid", "true")
        expect(page.locator('#notice[data-kind="error"]')).to_be_hidden()
        expect(page.locator('g.component[data-component="Pan"]')).to_have_count(0)
        page.locator('#props [name="setting-gpio"]').fill("17")
        page.locator('#props [name="add"]').click()
        settled(page)
        pan = page.locator('g.component[data-component="Pan"]')
        expect(pan).to_have_count(1)
        expect(page.locator("#props .props-head")).to_contain_text("Pan")
        expect(page.locator("#props .field-error")).to_have_count(0)
        # no port yet: the link row says what to do instead of an empty list
        expect(page.locator('#props [data-hint="link"]')).to_contain_text("add a port first")
        expect(page.locator('#props [name="link-from"]')).to_be_hidden()
        page.locator('#props [name="port"]').fill("aim")
        page.locator('#props [name="port-feature"]').select_option("angle")
        page.locator('#props [name="add-port"]').click()
        settled(page)
        expect(pan.locator("text.port-label")).to_have_text("aim → angle")
        expect(page.locator('#props [data-hint="link"]')).to_have_count(0)
        page.locator('#props [name="link-to"]').select_option("DistanceRead.range")
        page.locator('#props [name="add-link"]').click()
        settled(page)
        expect(page.locator("g.link")).to_have_count(2)
        shot(page, "studio-edit-component.png")
        page.keyboard.press("Control+s")
        expect(page.locator("#save")).to_have_attribute("data-dirty", "false")
        model = (folder / "model.yaml").read_text(encoding="utf-8")
        assert "Pan: {kind: actuator, ports: {aim: angle}}" in model
        deployment = (folder / "deployment.yaml").read_text(encoding="utf-8")
        assert "gpio: 17" in deployment
        assert "min_pulse_us" not in deployment  # the defaults are not written
        code, lines = check_lines(folder, tmp_path)
        assert code == 0, lines
        assert errors == [], errors
        page.close()


def test_a_dragged_node_keeps_its_place_in_the_layout_file(browser: Browser, tmp_path: Path) -> None:
    folder = tmp_path / "car"
    complete_car(folder)
    errors: list[str] = []
    with studio(["studio", str(folder), "--port", "0"], tmp_path) as proc:
        page = open_page(browser, proc.url, errors)
        show(page, "activity-motion")
        page.keyboard.press("f")  # all five lanes (it opens readable, from the left)
        moved = page.locator(node(page, "Stop", "left_off"))
        before = float(moved.get_attribute("data-x") or "nan"), float(moved.get_attribute("data-y") or "nan")
        box = moved.bounding_box()
        assert box
        page.mouse.move(box["x"] + 20, box["y"] + 15)
        page.mouse.down()
        page.mouse.move(box["x"] - 60, box["y"] + 140, steps=8)
        page.mouse.up()
        settled(page)
        after = float(moved.get_attribute("data-x") or "nan"), float(moved.get_attribute("data-y") or "nan")
        assert after[1] > before[1] + 40 and after[0] < before[0], (before, after)
        # the flow into it follows it; the other lanes stay laid out automatically
        edge = page.locator('svg.diagram g.edge[data-lane="Stop"][data-target="left_off"] path.line')
        assert str(round(after[1])) in (edge.get_attribute("d") or "")
        page.keyboard.press("Control+s")
        expect(page.locator("#save")).to_have_attribute("data-dirty", "false")
        layout = json.loads((folder / ".umlbot-studio.json").read_text(encoding="utf-8"))
        assert layout["positions"]["activity-motion"]["Stop/left_off"] == [round(after[0]), round(after[1])]
        assert (folder / "activities" / "motion.yaml").read_bytes() == (
            CAR_MODEL / "activities" / "motion.yaml").read_bytes()  # positions never go into the model
        page.close()
        again = open_page(browser, proc.url, errors)  # a new page draws it where it was put
        show(again, "activity-motion")
        there = again.locator(node(again, "Stop", "left_off"))
        assert float(there.get_attribute("data-x") or "nan") == round(after[0])
        assert float(there.get_attribute("data-y") or "nan") == round(after[1])
        assert errors == [], errors
        again.close()


def test_the_properties_panel_shows_a_long_completion_list_whole(browser: Browser, tmp_path: Path) -> None:
    folder = tmp_path / "car"
    complete_car(folder)
    errors: list[str] = []
    with studio(["studio", str(folder), "--port", "0"], tmp_path) as proc:
        page = open_page(browser, proc.url, errors)
        show(page, "activity-motion")
        page.keyboard.press("f")  # all five lanes (it opens readable, from the left)
        click_node(page, "Stop", "left_off")
        call = page.locator('#props input[name="call"]')
        call.click()
        call.press("Home")  # at the start of the call: every name is offered
        items = page.locator("#props .completions li")
        expect(items.nth(7)).to_be_visible()
        assert items.count() >= 8
        # the list is not cut by the panel: its 8th item is what is drawn at its place, inside the window
        box = items.nth(7).bounding_box()
        assert box and box["y"] + box["height"] <= 1000
        hit = page.evaluate(f"document.elementFromPoint({box['x'] + 5}, {box['y'] + box['height'] / 2})"
                            "?.closest('li')?.dataset.label")
        assert hit == items.nth(7).get_attribute("data-label"), hit
        shot(page, "studio-edit-completion-list.png")
        call.press("Escape")
        # a component's properties: the panel scrolls to its last row
        show(page, "components")
        page.locator('g.component[data-component="Sensor"]').click()
        add_link = page.locator('#props [name="add-link"]')
        add_link.scroll_into_view_if_needed()
        expect(add_link).to_be_in_viewport()
        shot(page, "studio-edit-component-props.png")
        assert page.evaluate("window.__studio.edit.dirty") is False  # looking changed nothing
        assert errors == [], errors
        page.close()


def test_deleting_a_lane_with_nodes_or_a_component_in_use_asks_first(
        browser: Browser, tmp_path: Path) -> None:
    folder = tmp_path / "car"
    complete_car(folder)
    errors: list[str] = []
    with studio(["studio", str(folder), "--port", "0"], tmp_path) as proc:
        page = open_page(browser, proc.url, errors)
        show(page, "activity-motion")
        page.keyboard.press("f")  # all five lanes (it opens readable, from the left)
        lane = page.locator('svg.diagram g.lane[data-lane="Stop"]')
        nodes = lane.locator("g.node").count()
        lane.locator(".lane-title").first.click()
        page.locator('#props [name="remove-lane"]').click()
        confirm = page.locator('#notice[data-kind="confirm"]')
        expect(confirm).to_contain_text(f"Delete the swimlane Stop with its {nodes} nodes?")
        shot(page, "studio-edit-confirm-lane.png")
        confirm.locator('[data-action="cancel"]').click()
        expect(confirm).to_be_hidden()
        expect(lane).to_have_count(1)
        assert page.evaluate("window.__studio.edit.dirty") is False  # nothing went
        page.locator('#props [name="remove-lane"]').click()
        confirm.locator('[data-action="confirm"]').click()
        settled(page)
        expect(lane).to_have_count(0)
        # a component that lanes call
        show(page, "components")
        page.locator('g.component[data-component="LeftActuator"]').click()
        page.locator('#props [name="remove"]').click()
        expect(confirm).to_contain_text("Delete the component LeftActuator?")
        expect(confirm).to_contain_text("nodes call it")
        confirm.locator('[data-action="cancel"]').click()
        expect(page.locator('g.component[data-component="LeftActuator"]')).to_have_count(1)
        assert errors == [], errors
        page.close()


def test_a_node_and_a_lane_renamed_in_the_page_are_renamed_in_the_drawing_and_the_file(
        browser: Browser, tmp_path: Path) -> None:
    folder = tmp_path / "car"
    complete_car(folder)
    errors: list[str] = []
    with studio(["studio", str(folder), "--port", "0"], tmp_path) as proc:
        page = open_page(browser, proc.url, errors)
        show(page, "activity-motion")
        page.keyboard.press("f")  # all five lanes (it opens readable, from the left)
        page.locator(node(page, "Stop", "left_off")).dblclick()  # its name, ready to be typed over
        name = page.locator('#props input[name="rename"]')
        expect(name).to_be_focused()
        expect(name).to_have_value("left_off")
        name.fill("stopped")  # taken: said at the field, nothing changes
        name.press("Enter")
        settled(page)
        expect(page.locator('#props .field-error[data-field="new_id"]')).to_contain_text(
            "id: is taken by another node of this swimlane")
        shot(page, "studio-edit-rename.png")
        assert page.evaluate("window.__studio.edit.dirty") is False
        name.fill("left_motor_off")
        name.press("Enter")
        settled(page)
        expect(page.locator(node(page, "Stop", "left_motor_off"))).to_have_count(1)
        expect(page.locator(node(page, "Stop", "left_off"))).to_have_count(0)
        expect(page.locator("svg.diagram g.node.selected")).to_have_attribute("data-node", "left_motor_off")
        expect(page.locator('svg.diagram g.edge[data-lane="Stop"][data-source="both"]'
                            '[data-target="left_motor_off"]')).to_have_count(1)
        # a virtual lane, from its title; every call of it follows
        page.locator('svg.diagram g.lane[data-lane="Stop"] .lane-title').first.click()
        lane_name = page.locator('#props input[name="rename"]')
        lane_name.fill("Halt")
        page.locator('#props [name="apply-rename"]').click()
        settled(page)
        expect(page.locator('svg.diagram g.lane[data-lane="Halt"]')).to_have_count(1)
        expect(page.locator('#props input[name="rename"]')).to_have_value("Halt")
        expect(page.locator("#diagnostics li.error")).to_have_count(0)
        page.keyboard.press("Control+s")
        expect(page.locator("#save")).to_have_attribute("data-dirty", "false")
        motion = (folder / "activities" / "motion.yaml").read_text(encoding="utf-8")
        assert "  - lane: Halt                  # both sides at once\n" in motion
        assert "{id: both, kind: fork, targets: [left_motor_off, right_off]}" in motion
        assert ("{id: left_motor_off, kind: action, call: LeftActuator.enabled(false), next: stopped}"
                in motion)
        main = (folder / "activities" / "main.yaml").read_text(encoding="utf-8")
        assert "call: Stop" not in main and "{id: halt, kind: action, call: Halt, next: ping_ahead}" in main
        assert check_lines(folder, tmp_path) == (0, [])
        assert errors == [], errors
        page.close()


def test_unsaved_edits_kept_at_quit_are_offered_back(browser: Browser, tmp_path: Path) -> None:
    folder = tmp_path / "car"
    complete_car(folder)
    motion = folder / "activities" / "motion.yaml"
    before = motion.read_bytes()
    kept = before.decode().replace("LeftActuator.enabled(false), next: stopped",
                                   "LeftActuator.enabled(true), next: stopped")
    assert kept != before.decode()
    (folder / ".umlbot-studio-recovery.json").write_text(json.dumps(
        {"time": "2026-11-23 08:00:00", "files": {"activities/motion.yaml": kept}, "layout": None}))
    errors: list[str] = []
    with studio(["studio", str(folder), "--port", "0"], tmp_path) as proc:
        page = open_page(browser, proc.url, errors)
        offer = page.locator('#notice[data-kind="recovery"]')
        expect(offer).to_contain_text("activities/motion.yaml")
        expect(offer.locator('[data-action="restore"]')).to_have_text(
            "Restore the unsaved edits of 2026-11-23 08:00:00")
        expect(offer.locator('[data-action="discard"]')).to_be_visible()
        shot(page, "studio-edit-recovery.png")
        offer.locator('[data-action="restore"]').click()
        expect(page.locator("#save")).to_have_attribute("data-dirty", "true")
        assert motion.read_bytes() == before  # restored into the page only
        show(page, "activity-motion")
        expect(page.locator(node(page, "Stop", "left_off")).locator("text.label")).to_have_text(
            "LeftActuator.enabled(true)")
        page.keyboard.press("Control+s")
        expect(page.locator("#save")).to_have_attribute("data-dirty", "false")
        assert motion.read_text(encoding="utf-8") == kept
        assert not (folder / ".umlbot-studio-recovery.json").exists()
        assert errors == [], errors
        page.close()
