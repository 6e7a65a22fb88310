"""umlbot studio's panels as a person sees them, in a real browser (Debian's Chromium, Playwright).

The properties panel's id field after a rename, its undo and another selection; Ctrl-Z right after a
node was added; the toolbar's broker status during and after a Run; a laptop window (1280 x 720);
a pin wired twice and a name the compiler refuses, said at their fields with `umlbot check`'s own
lines; an empty folder (the component library, the starter's labelled name field); the recovery
notice's buttons; the end of a run in plain words; a called component's brief flash. Screenshots under out/.
"""

from __future__ import annotations

import json
import re
import shutil
import socket
import subprocess
from collections.abc import Iterator
from pathlib import Path

import pytest
from playwright.sync_api import Browser, Page, Route, expect
from robot_run import CAR_MODEL, umlbot_argv
from studio_support import chromium, shot, studio

WAIT_MS = 30_000


@pytest.fixture(scope="module")
def browser() -> Iterator[Browser]:
    with chromium() as launched:
        yield launched


def open_page(browser: Browser, url: str, errors: list[str], width: int = 1600, height: int = 1000) -> Page:
    page = browser.new_page(viewport={"width": width, "height": height})
    page.on("pageerror", lambda exc: errors.append(str(exc)))
    page.goto(url)
    page.set_default_timeout(WAIT_MS)
    page.wait_for_function("window.__studio && window.__studio.ready === true && !!window.__studio.edit")
    return page


def settled(page: Page) -> None:
    page.wait_for_function("window.__studio.edit.busy === false")
    page.wait_for_function("window.__studio.ready === true")


def show(page: Page, diagram: str) -> None:
    page.locator(f'#diagram-list [data-diagram="{diagram}"]').click()
    expect(page.locator(f'svg[data-diagram="{diagram}"]')).to_be_visible()
    settled(page)


def node(lane: str, node_id: str) -> str:
    return f'svg.diagram g.node[data-lane="{lane}"][data-node="{node_id}"]'


def check_line(folder: Path, files: dict[str, str], containing: str, shown: Path) -> str:
    """The line `umlbot check` prints for the page's working copy `files`, naming `shown`."""
    copy = folder.parent / f"{folder.name}-check"
    shutil.rmtree(copy, ignore_errors=True)
    for rel, text in files.items():
        (copy / rel).parent.mkdir(parents=True, exist_ok=True)
        (copy / rel).write_text(text, encoding="utf-8")
    done = subprocess.run(umlbot_argv("check", str(copy)), capture_output=True, text=True, timeout=120,
                          check=False)
    lines = [x for x in (done.stdout + done.stderr).splitlines() if containing in x]
    assert len(lines) == 1, (done.stdout, done.stderr)
    return lines[0].replace(str(copy), str(shown))


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return int(s.getsockname()[1])


def test_the_id_field_shows_the_selected_nodes_id_after_a_rename_its_undo_and_another_selection(
        browser: Browser, tmp_path: Path) -> None:
    folder = tmp_path / "car"
    shutil.copytree(CAR_MODEL, folder)
    errors: list[str] = []
    with studio(["studio", str(folder), "--port", "0"], tmp_path) as proc:
        page = open_page(browser, proc.url, errors)
        show(page, "activity-motion")
        page.keyboard.press("f")
        page.locator(node("Stop", "left_off")).dblclick()
        field = page.locator('#props input[name="rename"]')
        head = page.locator("#props .props-head")
        field.fill("left_motor_off")
        field.press("Enter")
        settled(page)
        expect(field).to_have_value("left_motor_off")
        # Ctrl-Z in the id field with nothing typed in it: the model's undo, and the field follows
        field.click()
        page.keyboard.press("Control+z")
        settled(page)
        expect(page.locator(node("Stop", "left_off"))).to_have_count(1)
        expect(head).to_have_text("action · left_off")
        expect(field).to_have_value("left_off")
        page.keyboard.press("Control+Shift+z")
        settled(page)
        expect(head).to_have_text("action · left_motor_off")
        expect(field).to_have_value("left_motor_off")
        # the toolbar's Undo too
        page.locator("#undo").click()
        settled(page)
        expect(field).to_have_value("left_off")
        # another node: its id, also when something was typed (and not sent) in the field before
        field.fill("half_typed")
        page.locator(node("Stop", "right_off")).click()
        expect(head).to_have_text("action · right_off")
        expect(field).to_have_value("right_off")
        page.locator(node("Stop", "both")).click()
        expect(field).to_have_value("both")
        shot(page, "studio-id-field.png")

        # Ctrl-Z right after adding a node from the palette takes the node away (the new node's
        # name field has the focus: nothing is typed in it, so the key is the model's undo)
        page.locator('#palette [data-kind="action"]').click()
        settled(page)
        added = str(page.locator("svg.diagram g.node.selected").get_attribute("data-node"))
        expect(page.locator(node("Stop", added))).to_have_count(1)
        assert page.evaluate("document.activeElement.closest('#props') !== null")
        page.keyboard.press("Control+z")
        settled(page)
        expect(page.locator(node("Stop", added))).to_have_count(0)
        assert page.evaluate("window.__studio.edit.dirty") is False
        # typed text in a field keeps the field's own undo
        page.locator(node("Stop", "both")).click()
        field.fill("bothx")
        page.keyboard.press("Control+z")
        page.wait_for_timeout(300)
        expect(page.locator(node("Stop", "both"))).to_have_count(1)
        assert page.evaluate("window.__studio.edit.dirty") is False
        page.close()
    assert errors == [], errors


def test_the_broker_status_follows_a_run_and_its_end_is_said_in_plain_words(
        browser: Browser, tmp_path: Path) -> None:
    folder = tmp_path / "car"
    shutil.copytree(CAR_MODEL, folder)
    errors: list[str] = []
    nobody = f"mqtt://127.0.0.1:{free_port()}"  # the robot's broker is not there
    with studio(["studio", str(folder), "--port", "0"], tmp_path, broker_url=nobody) as proc:
        page = open_page(browser, proc.url, errors)
        status = page.locator("#broker-status")
        expect(status).to_have_attribute("data-state", "failed")
        expect(status).to_contain_text("Connection refused")
        page.locator("#track").select_option("corridor")
        page.locator("#run-speed").select_option("1")
        assert "real time" in (page.locator("#run-speed").get_attribute("title") or "")
        page.locator("#run").click()
        # the run's own broker: said once connected (it was stuck at "connecting…")
        expect(status).to_have_attribute("data-source", "run")
        expect(status).to_have_text("sim broker connected")
        expect(status).to_have_attribute("data-state", "connected")
        page.wait_for_function("document.querySelectorAll('#sim .ping').length > 0")
        expect(page.locator("#sim .sim-info")).to_contain_text("simulated time")
        shot(page, "studio-run-broker.png")
        page.locator("#stop").click()
        notice = page.locator('#notice[data-kind="run-ended"]')
        expect(notice).to_be_visible()
        expect(notice).to_contain_text(re.compile(r"^You stopped the run \(\d+\.\d s of simulated driving, "))
        assert not re.search(r"interrupted|orchestrator", notice.text_content() or "")
        # after the run: the robot's broker again
        expect(status).to_have_attribute("data-source", "robot")
        expect(status).to_have_attribute("data-state", "failed")
        page.close()
    assert errors == [], errors


def test_a_laptop_window_shows_the_whole_toolbar_and_the_calls(browser: Browser, tmp_path: Path) -> None:
    folder = tmp_path / "car"
    shutil.copytree(CAR_MODEL, folder)
    errors: list[str] = []
    with studio(["studio", str(folder), "--port", "0"], tmp_path) as proc:
        page = open_page(browser, proc.url, errors, 1280, 720)
        show(page, "activity-main")
        page.locator("#track").select_option("corridor")
        page.locator("#run-speed").select_option("1")
        page.locator("#run").click()
        page.wait_for_function("document.querySelectorAll('#calls tbody tr').length >= 6")
        # a node's properties too: one the view shows. Follow off first: the view follows the run
        # and could move the node off screen between finding it and clicking it
        page.locator("#follow").click()
        expect(page.locator("#follow")).to_have_attribute("aria-pressed", "false")
        shown = page.evaluate("""() => {
          const c = document.querySelector('#canvas').getBoundingClientRect();
          return [...document.querySelectorAll('svg.diagram g.node[data-lane="RaspberryPI"]')].map((g) => {
            const r = g.getBoundingClientRect();
            const inside = r.left > c.left && r.right < c.right && r.top > c.top + 60 && r.bottom < c.bottom;
            return r.width > 0 && inside ? g.dataset.node : null;
          }).find((n) => n) ?? null;
        }""")
        assert shown is not None
        page.locator(f'svg.diagram g.node[data-lane="RaspberryPI"][data-node="{shown}"]').click()
        page.wait_for_timeout(500)
        shot(page, "studio-laptop-run.png")
        # every control of the toolbar is inside the window, its text whole; only the source path
        # and the status may be cut, with their whole text as the tooltip
        cut = page.evaluate("""() => {
          const out = [];
          for (const e of document.querySelectorAll('#toolbar > *, #edit-tools > *')) {
            if (e.hidden || !e.getClientRects().length || e.id === 'edit-tools') continue;
            const r = e.getBoundingClientRect();
            const whole = e.scrollWidth <= e.clientWidth + 1 || e.tagName === 'SELECT';
            const name = e.id || e.className;
            const titled = ['source', 'orchestrator-status'].includes(e.id) && e.title === e.textContent;
            if (r.left < 0 || r.right > innerWidth + 0.5 || r.bottom > 120) out.push(`${name}: outside`);
            else if (!whole && !titled) out.push(`${name}: cut`);
          }
          return out;
        }""")
        assert cut == [], cut
        for control in ("#undo", "#redo", "#save", "#track", "#run", "#stop", "#fit", "#connection"):
            expect(page.locator(control)).to_be_in_viewport()
        expect(page.locator("#title")).to_have_text(re.compile(r"^car · robot car$"))
        # the calls panel has room for rows, and what a call says is wrapped, not cut
        box = page.locator("#calls-panel .scroll").bounding_box()
        assert box and box["height"] >= 120 and box["y"] + box["height"] <= 720, box
        cells = page.evaluate("""() => [...document.querySelectorAll('#calls tbody tr:first-child td')]
          .map((td) => [td.className, td.scrollWidth <= td.clientWidth + 1,
                        td.getBoundingClientRect().right <= innerWidth + 0.5])""")
        assert cells and all(whole and inside for _, whole, inside in cells), cells
        page.locator("#stop").click()
        page.close()
    assert errors == [], errors


def test_a_pin_wired_twice_and_a_builtins_name_are_said_at_their_fields_as_umlbot_check_says_them(
        browser: Browser, tmp_path: Path) -> None:
    folder = tmp_path / "car"
    shutil.copytree(CAR_MODEL, folder)
    errors: list[str] = []
    with studio(["studio", str(folder), "--port", "0"], tmp_path) as proc:
        page = open_page(browser, proc.url, errors)
        show(page, "components")
        page.locator('g.component[data-component="RightActuator"]').click()
        page.locator('#props [name="setting-in1"]').fill("22")  # LeftActuator's in1
        page.locator('#props [name="apply-deployment"]').click()
        settled(page)
        files = page.evaluate("() => fetch('/api/files').then((r) => r.json())")["files"]
        line = check_line(folder, files, "GPIO 22", folder)
        at_field = page.locator('#props .field-error[data-field="settings.in1"]')
        expect(at_field).to_have_text(line)
        expect(at_field).to_be_in_viewport()  # the panel shows it (it was scrolled to its Apply button)
        expect(page.locator('#props [name="setting-in1"]')).to_have_attribute("aria-invalid", "true")
        assert line in page.locator("#diagnostics li .text").all_text_contents()
        shot(page, "studio-shared-pin.png")
        page.keyboard.press("Control+z")
        settled(page)
        expect(page.locator("#props .field-error")).to_have_count(0)

        # the compiler decides which names may be: a swimlane named msleep is its error, said at
        # the field (nothing changes); a node id msleep it accepts, and so does the page
        show(page, "activity-motion")
        page.keyboard.press("f")
        page.locator('svg.diagram g.lane[data-lane="Stop"] .lane-title').first.click()
        name = page.locator('#props input[name="rename"]')
        name.fill("msleep")
        name.press("Enter")
        settled(page)
        renamed = {**files, "activities/motion.yaml": files["activities/motion.yaml"].replace(
            "- lane: Stop ", "- lane: msleep ")}
        expect(page.locator('#props .field-error[data-field="new_name"]')).to_have_text(
            check_line(folder, renamed, "'msleep' is a reserved", folder))
        assert page.evaluate("window.__studio.edit.dirty") is False
        page.locator(node("Stop", "left_off")).dblclick()
        name.fill("msleep")
        name.press("Enter")
        settled(page)
        expect(page.locator(node("Stop", "msleep"))).to_have_count(1)
        expect(page.locator("#props .field-error")).to_have_count(0)
        expect(page.locator("#diagnostics li.error")).to_have_count(0)
        page.close()
    assert errors == [], errors


def test_an_empty_folder_shows_the_library_says_why_parts_wait_and_labels_the_name(
        browser: Browser, tmp_path: Path) -> None:
    folder = tmp_path / "bot"
    errors: list[str] = []
    with studio(["studio", "--new", str(folder), "--port", "0"], tmp_path) as proc:
        proc.wait_line("does not exist yet: the page offers a starter model")  # the terminal says it too
        page = open_page(browser, proc.url, errors)
        palette = page.locator("#palette")
        expect(palette.locator('[data-impl="l298n"]')).to_contain_text("dutycycle")
        expect(palette.locator('[data-hint="no-model"]')).to_contain_text("create it first")
        palette.locator('[data-impl="servo"]').click()
        expect(page.locator('#props [data-hint="no-model"]')).to_contain_text("create it first")
        expect(page.locator('#props [name="add"]')).to_have_count(0)
        # the starter's name field has a visible label
        name = page.get_by_label("Robot name")
        expect(name).to_be_visible()
        expect(name).to_have_attribute("name", "model-name")
        shot(page, "studio-edit-empty-library.png")
        name.fill("bot")
        page.locator("#new-model").click()
        settled(page)
        show(page, "components")
        page.locator('#palette [data-impl="servo"]').click()
        expect(page.locator('#props [name="add"]')).to_be_visible()
        expect(page.locator('[data-hint="no-model"]')).to_have_count(0)
        page.close()
    assert errors == [], errors


def test_the_recovery_notice_says_what_each_button_does_and_later_keeps_the_edits(
        browser: Browser, tmp_path: Path) -> None:
    folder = tmp_path / "car"
    shutil.copytree(CAR_MODEL, folder)
    kept = (folder / "activities" / "motion.yaml").read_text(encoding="utf-8").replace(
        "LeftActuator.enabled(false), next: stopped", "LeftActuator.enabled(true), next: stopped")
    recovery = folder / ".umlbot-studio-recovery.json"
    recovery.write_text(json.dumps({"time": "2026-11-23 08:00:00",
                                    "files": {"activities/motion.yaml": kept}, "layout": None}))
    errors: list[str] = []
    with studio(["studio", str(folder), "--port", "0"], tmp_path) as proc:
        page = open_page(browser, proc.url, errors)
        offer = page.locator('#notice[data-kind="recovery"]')
        expect(offer.locator('[data-action="discard"]')).to_have_text("Discard them")
        assert "for good" in (offer.locator('[data-action="discard"]').get_attribute("title") or "")
        later = offer.locator('[data-action="dismiss"]')
        expect(later).to_have_text("Decide later")
        assert "offers them again" in (later.get_attribute("title") or "")
        shot(page, "studio-recovery-notice.png")
        later.click()
        expect(offer).to_be_hidden()
        assert recovery.is_file()  # nothing was discarded
        page.reload()
        page.wait_for_function("window.__studio && window.__studio.ready === true && !!window.__studio.edit")
        expect(page.locator('#notice[data-kind="recovery"]')).to_be_visible()
        page.close()
    assert errors == [], errors


def test_a_page_opened_while_a_conflict_stands_shows_the_conflict_not_the_end_of_a_run(
        browser: Browser, tmp_path: Path) -> None:
    folder = tmp_path / "car"
    shutil.copytree(CAR_MODEL, folder)
    main = folder / "activities" / "main.yaml"
    errors: list[str] = []
    with studio(["studio", str(folder), "--port", "0"], tmp_path) as proc:
        page = open_page(browser, proc.url, errors)
        show(page, "activity-main")
        page.locator("#track").select_option("corridor")
        page.locator("#run").click()
        expect(page.locator("#stop")).to_be_enabled()
        page.locator("#stop").click()
        expect(page.locator('#notice[data-kind="run-ended"]')).to_be_visible()
        # an unsaved edit, and the same file changed on disk: a conflict stands (the view followed
        # the run down its lane: the node is brought back into view, as a person would pan to it)
        page.evaluate("window.__studio.reveal('RaspberryPI', 'set_speed')")
        page.locator(node("RaspberryPI", "set_speed")).click()
        value = page.locator('#props input[name="value"]')
        value.fill("55")
        value.press("Enter")
        settled(page)
        theirs = main.read_text(encoding="utf-8").replace("value: 300}", "value: 333}")
        main.write_text(theirs, encoding="utf-8")
        expect(page.locator('#notice[data-kind="conflict"]')).to_be_visible()
        page.close()
        # a new page (a browser that has not been told how the run ended): the conflict is what it shows
        again = open_page(browser, proc.url, errors)
        notice = again.locator("#notice")
        expect(notice).to_have_attribute("data-kind", "conflict")
        again.wait_for_timeout(1000)
        expect(notice).to_have_attribute("data-kind", "conflict")
        expect(notice).to_be_visible()
        expect(notice).to_contain_text("activities/main.yaml changed on disk while you have unsaved edits")
        expect(notice.locator('[data-action="reload"]')).to_be_visible()
        shot(again, "studio-conflict-at-open.png")
        again.close()
    assert errors == [], errors


def test_the_palette_and_a_nodes_fields_are_the_servers_node_kinds(browser: Browser, tmp_path: Path) -> None:
    # the page holds no list of node kinds or fields: a library that says otherwise is what it shows
    folder = tmp_path / "car"
    shutil.copytree(CAR_MODEL, folder)
    errors: list[str] = []

    def changed(route: Route) -> None:
        answer = route.fetch()
        library = answer.json()
        library["node_kinds"]["wait"] = {"doc": "waits a while", "fields": {}}
        library["node_kinds"]["action"]["fields"]["note"] = {"type": "expression", "required": False,
                                                             "doc": "a note"}
        del library["node_kinds"]["accept"]
        route.fulfill(response=answer, json=library)

    with studio(["studio", str(folder), "--port", "0"], tmp_path) as proc:
        page = browser.new_page(viewport={"width": 1600, "height": 1000})
        page.on("pageerror", lambda exc: errors.append(str(exc)))
        page.route("**/api/library", changed)
        page.goto(proc.url)
        page.set_default_timeout(WAIT_MS)
        page.wait_for_function("window.__studio && window.__studio.ready === true && !!window.__studio.edit")
        show(page, "activity-main")
        expect(page.locator('#palette .node-kind[data-kind="wait"]')).to_have_count(1)
        kinds = page.locator("#palette .node-kind").evaluate_all("(l) => l.map((e) => e.dataset.kind)")
        assert kinds == ["start", "end", "action", "datastore", "decision", "fork", "join", "send", "wait"]
        # the server's doc, and how the palette's button is used
        assert page.locator('#palette .node-kind[data-kind="wait"]').get_attribute("title") == (
            "waits a while (Enter adds it after the selected node)")
        page.keyboard.press("f")  # all of it: the action is further down
        page.locator(node("RaspberryPI", "left_power")).click()
        expect(page.locator('#props input[name="call"]')).to_have_class(re.compile(r"(^|\s)code(\s|$)"))
        expect(page.locator('#props input[name="note"]')).to_have_class(re.compile(r"(^|\s)code(\s|$)"))
        expect(page.locator('#props input[name="next"]')).to_have_count(0)  # a flow: edited by connecting
        page.close()
    assert errors == [], errors


def test_a_called_component_flashes_briefly_without_an_animation_running_in_every_frame(
        browser: Browser, tmp_path: Path) -> None:
    """A component the robot calls is lit (class `flash`) for a moment and then not, each time; its
    box never carries a running animation (a fading fill would repaint the diagram in every frame
    while the robot keeps calling, and the page would take the studio's messages late)."""
    folder = tmp_path / "car"
    shutil.copytree(CAR_MODEL, folder)
    errors: list[str] = []
    with studio(["studio", str(folder), "--port", "0"], tmp_path) as proc:
        page = open_page(browser, proc.url, errors)
        show(page, "components")
        page.evaluate("""() => {
          window.__flashes = {lit: [], animated: 0};
          const since = new Map();
          new MutationObserver((records) => {
            for (const r of records) {
              const box = r.target;
              if (box.classList.contains('flash')) {
                if (!since.has(box)) since.set(box, performance.now());
              } else if (since.has(box)) {
                window.__flashes.lit.push(performance.now() - since.get(box));
                since.delete(box);
              }
            }
          }).observe(document.querySelector('svg[data-diagram="components"]'),
                     {subtree: true, attributes: true, attributeFilter: ['class']});
          const look = () => {
            const boxes = document.querySelectorAll('svg[data-diagram="components"] g.component rect.box');
            for (const box of boxes) window.__flashes.animated += box.getAnimations().length;
            requestAnimationFrame(look);
          };
          requestAnimationFrame(look);
        }""")
        page.locator("#track").select_option("corridor")
        page.locator("#run-speed").select_option("1")
        page.locator("#run").click()
        page.wait_for_function("window.__flashes.lit.length >= 5")
        flashes = page.evaluate("window.__flashes")
        assert flashes["animated"] == 0, flashes
        # lit for FLASH_MS (200 ms) and then not: never left on (the observer's callbacks and the
        # timers of a busy machine run late, so only the bounds are sure)
        assert all(0 < ms <= 3000 for ms in flashes["lit"]), flashes
    assert errors == []
