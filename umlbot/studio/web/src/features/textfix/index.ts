// A model file the compiler cannot read as YAML (a syntax error) is not lost from the page: the
// sidebar lists it under the diagrams, and its text opens over the canvas with the line of the
// error marked and the caret at the error; the person fixes the text there and applies it (an
// edit like any other: undo takes it back, Save writes it). A problem's `file:line` in the
// Diagnostics opens any model file so, at that line.

import { $, el } from "../../core/dom";
import type { Studio } from "../../core/studio";
import { type BrokenFile, brokenFiles, lineNumbers, offsetOf } from "./find";

export function install({ bus, store }: Studio): void {
  const listEl = $<HTMLUListElement>("#broken-files");
  const view = $<HTMLElement>("#text-fix");
  const title = $<HTMLElement>("#text-fix-title");
  const where = $<HTMLElement>("#text-fix-problem");
  const gutter = $<HTMLElement>("#text-fix-lines");
  const mark = $<HTMLElement>("#text-fix-mark");
  const area = $<HTMLTextAreaElement>("#text-fix-text");
  const apply = $<HTMLButtonElement>("#text-fix-apply");
  const close = $<HTMLButtonElement>("#text-fix-close");
  let shown: BrokenFile | null = null;
  let fixing = false; // the file shown cannot be read (not only a line looked at)
  let broken: BrokenFile[] = [];

  /** The marked line's bar follows the text's scrolling (and the gutter with it). */
  const place = (): void => {
    gutter.scrollTop = area.scrollTop;
    if (!shown) return;
    const lh = Number.parseFloat(getComputedStyle(area).lineHeight) || 16;
    const pad = Number.parseFloat(getComputedStyle(area).paddingTop) || 0;
    mark.style.top = `${pad + (shown.line - 1) * lh - area.scrollTop}px`;
    mark.style.height = `${lh}px`;
  };

  const markError = (b: BrokenFile): void => {
    shown = b;
    view.dataset.file = b.file;
    view.dataset.line = String(b.line);
    title.textContent = b.file;
    const fix = broken.some((x) => x.file === b.file) ? " Fix the text here, then apply it." : "";
    where.textContent = `line ${b.line}, column ${b.column}: ${b.problem.replace(/\.$/, "")}.${fix}`;
    gutter.textContent = lineNumbers(area.value);
    for (const s of gutter.querySelectorAll(".err")) s.classList.remove("err");
    place();
  };

  const open = async (b: BrokenFile): Promise<void> => {
    let text = "";
    try {
      const res = await fetch("/api/files");
      const data = (await res.json()) as { files: Record<string, string> };
      text = data.files?.[b.file] ?? "";
    } catch (exc) {
      bus.request("notice.show", { kind: "error", text: `Cannot read ${b.file} from the studio: ${String(exc)}` });
      return;
    }
    view.hidden = false;
    fixing = broken.some((x) => x.file === b.file);
    area.value = text;
    markError(b);
    const at = offsetOf(text, b.line, b.column);
    area.focus();
    area.setSelectionRange(at, at);
    // the error's line in view: a few lines above it on top
    const lh = Number.parseFloat(getComputedStyle(area).lineHeight) || 16;
    area.scrollTop = Math.max(0, (b.line - 4) * lh);
    place();
  };

  const hide = (): void => {
    view.hidden = true;
    shown = null;
  };

  const render = (): void => {
    listEl.replaceChildren();
    listEl.hidden = broken.length === 0 || !store.edit;
    for (const b of broken) {
      const li = el("li", { "data-file": b.file }, listEl);
      const btn = el("button", { type: "button", title: `${b.file}:${b.line}:${b.column}: ${b.problem}` }, li);
      el("span", { class: "name" }, btn, `⚠ ${b.file}`);
      el("span", { class: "sub" }, btn, `cannot be read: line ${b.line} — fix it here`);
      btn.addEventListener("click", () => void open(b));
    }
    if (shown && fixing) {
      const still = broken.find((b) => b.file === shown!.file);
      if (still) markError(still);
      else {
        const fixed = shown.file;
        hide();
        bus.request("notice.show", { kind: "saved", text: `${fixed} reads again.`, hideAfterMs: 4000 });
      }
    }
  };

  apply.addEventListener("click", async () => {
    if (!shown) return;
    const file = shown.file;
    const ok = await bus.request("edit.send", [{ op: "set_text", file, text: area.value }]);
    if (ok) {
      const b = broken.find((x) => x.file === file);
      if (!b) hide();
    }
  });
  close.addEventListener("click", hide);
  area.addEventListener("scroll", place);
  area.addEventListener("input", () => {
    gutter.textContent = lineNumbers(area.value);
  });
  area.addEventListener("keydown", (ev) => {
    ev.stopPropagation(); // typing is text, not the page's keys (f, l, Delete…)
    if (ev.key === "Escape") hide();
    if ((ev.ctrlKey || ev.metaKey) && ev.key === "Enter") apply.click();
  });
  bus.on("diagnostics.changed", (list) => {
    broken = brokenFiles(list);
    render();
  });
  bus.on("file.show", (file, line = 1, column = 1, problem = "") => {
    // a file that cannot be read: its first problem; any other: the line asked for
    const b = broken.find((x) => x.file === file) ?? { file, line, column, problem };
    void open(b);
  });
}
