#!/usr/bin/env python3
"""Refresh the layout caches shipped beside the reference models (`layout-cache.json`).

For each model: `umlbot studio MODEL` with an empty user cache and the shipped file ignored
(`UMLBOT_LAYOUT_CACHE=user`), Debian's Chromium (Playwright) opens every activity diagram, ELK
lays out each lane in the page and the page sends its layouts to the server; what the server kept
becomes the model's shipped file (only today's entries: a refresh never keeps a stale one).
tests/test_studio_layout_cache_browser.py fails when a shipped file no longer matches what the
page gives ELK (a change of the layout code, of ELK, of a node's size or of the model).

    python scripts/layout_cache.py [MODEL ...]      # default: the reference models; make layout-cache

The keys hold the nodes' sizes as this machine's browser measures their text: a machine with other
fonts misses the shipped entries (and keeps its own in its user cache). docs/studio.md, "Layout cache".
"""

from __future__ import annotations

import argparse
import os
import re
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from playwright.sync_api import ViewportSize, sync_playwright

from umlbot.studio.layouts import SHIPPED_NAME, read_shipped, write_shipped

ROOT = Path(__file__).resolve().parent.parent
REFERENCE = [ROOT / "models" / "robot_car", ROOT / "models" / "stereo_car"]
CHROMIUM = "/usr/bin/chromium"
CHROMIUM_ARGS = ["--no-sandbox", "--disable-gpu", "--disable-background-networking",
                 "--disable-component-update", "--disable-sync", "--no-first-run"]
URL_LINE = re.compile(r"umlbot studio: (http://\S+)")
WAIT_MS = 120_000
#: the viewport of the page (the layout does not depend on it; the reference of bench/studio.py).
VIEWPORT: ViewportSize = {"width": 1600, "height": 1000}


def refresh(model: Path) -> int:
    """Write `model`'s shipped file afresh; the number of layouts in it."""
    with tempfile.TemporaryDirectory(prefix="umlbot-layouts-") as tmp:
        env = {k: v for k, v in os.environ.items() if k not in ("UMLBOT_ROBOT", "UMLBOT_BROKER")}
        env.update(XDG_CACHE_HOME=tmp, UMLBOT_LAYOUT_CACHE="user", UMLBOT_BROKER="mqtt://127.0.0.1:1")
        argv = [sys.executable, "-c", "from umlbot.cli import main; main()", "studio", str(model),
                "--port", "0"]
        with open(Path(tmp) / "studio.log", "wb") as err:
            proc = subprocess.Popen(argv, stdout=subprocess.PIPE, stderr=err, env=env, text=True)
        try:
            url = _url(proc)
            with sync_playwright() as pw:
                browser = pw.chromium.launch(executable_path=CHROMIUM, args=CHROMIUM_ARGS)
                try:
                    page = browser.new_page(viewport=VIEWPORT)
                    page.set_default_timeout(WAIT_MS)
                    page.goto(url)
                    page.wait_for_function("window.__studio && window.__studio.ready === true")
                    ids = page.eval_on_selector_all("#diagram-list [data-diagram]",
                                                    "els => els.map(e => e.dataset.diagram)")
                    for diagram in ids:
                        if not diagram.startswith("activity-"):
                            continue
                        page.locator(f'#diagram-list [data-diagram="{diagram}"]').click()
                        page.wait_for_selector(f'svg[data-diagram="{diagram}"] g.node')
                    # every layout ELK made is kept by the server (sent in the background)
                    page.wait_for_function("(() => { const s = window.__studio.layouts; "
                                           "return s.elk > 0 && s.kept === s.elk; })()")
                finally:
                    browser.close()
        finally:
            proc.terminate()
            proc.wait(15)
        folder = Path(tmp) / "umlbot" / "layouts"
        layouts = {}
        for path in sorted(folder.glob("*.json")):
            layouts.update(read_shipped_entry(path))
    write_shipped(model / SHIPPED_NAME, layouts)
    assert read_shipped(model / SHIPPED_NAME).keys() == layouts.keys()
    return len(layouts)


def read_shipped_entry(path: Path) -> dict[str, dict[str, object]]:
    """One user-cache entry as {key: layout}."""
    import json

    from umlbot.studio.layouts import check_layout

    return {path.stem: check_layout(json.loads(path.read_text(encoding="utf-8"))["layout"])}


def _url(proc: subprocess.Popen[str]) -> str:
    assert proc.stdout is not None
    deadline = time.monotonic() + 60
    while time.monotonic() < deadline:
        line = proc.stdout.readline()
        if not line:
            break
        match = URL_LINE.search(line)
        if match:
            return match.group(1)
    raise SystemExit("the studio printed no URL")


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("models", nargs="*", type=Path, help="model folders (default: the reference models)")
    args = parser.parse_args()
    for model in args.models or REFERENCE:
        count = refresh(model)
        print(f"{model / SHIPPED_NAME}: {count} lane layouts")
    return 0


if __name__ == "__main__":
    sys.exit(main())
