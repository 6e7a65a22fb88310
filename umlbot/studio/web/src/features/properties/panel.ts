// The properties panel's frame: what every part of it uses (the selection, sending edits, drawing
// again), the drawing itself (the selection's form, the focused field kept across a redraw), and
// the small pieces the forms are made of.

import { el } from "../../core/dom";
import type { Selection } from "../../core/selection";
import type { EditSession } from "../../core/store";
import type { Studio } from "../../core/studio";
import type { Op } from "../../model/types";

export class Panel {
  readonly el: HTMLElement;
  /** the next drawing of a component's properties shows its first deployment problem */
  revealProblems = false;
  /** draws the selection's form into the panel's body (set by index.ts) */
  drawBody: (body: HTMLElement, s: NonNullable<Selection>) => void = () => undefined;

  constructor(
    readonly studio: Studio,
    el: HTMLElement,
  ) {
    this.el = el;
  }

  get edit(): EditSession {
    return this.studio.store.edit!;
  }

  /** Send edit operations; true when applied (a problem with a field of `form` is shown there). */
  send(ops: Op[], form?: HTMLElement): Promise<boolean> {
    return this.studio.bus.request("edit.send", ops, form) ?? Promise.resolve(false);
  }

  /** Select `sel`, draw the panel again and outline the selection. */
  select(sel: Selection): void {
    this.edit.selection = sel;
    this.render();
    this.studio.bus.request("selection.highlight");
  }

  /** Draw the panel for the selection. An answer redraws the panel: the focused field keeps its
   * focus and caret, and the text typed in it that is not sent yet; a field with nothing typed
   * shows the model's value (after an undo or a rename, the value now, not the one it showed). */
  render(): void {
    const { bus, canvas } = this.studio;
    const p = this.el;
    const edit = this.edit;
    const a = document.activeElement;
    const typing =
      a instanceof HTMLInputElement && p.contains(a) && a.name
        ? {
            sel: `[name="${CSS.escape(a.name)}"]${a.dataset.target ? `[data-target="${CSS.escape(a.dataset.target)}"]` : ""}`,
            value: a.value,
            typed: a.value !== a.defaultValue,
            start: a.selectionStart,
            end: a.selectionEnd,
            what: JSON.stringify(edit.selection),
          }
        : null;
    p.replaceChildren();
    if (typing)
      queueMicrotask(() => {
        const again = p.querySelector<HTMLInputElement>(typing.sel);
        if (!again || typing.what !== JSON.stringify(edit.selection)) return;
        if (typing.typed && again.value !== typing.value) again.value = typing.value;
        again.focus();
        if (typing.start !== null && typing.end !== null) again.setSelectionRange(typing.start, typing.end);
      });
    el("div", { class: "panel-title" }, p, "Properties");
    const body = el("div", { class: "props-body" }, p);
    const s = edit.selection;
    bus.request("selection.highlight");
    p.dataset.selection = s ? s.type : "";
    if (!s && edit.info.empty) {
      el(
        "div",
        { class: "hint", "data-hint": "no-model" },
        body,
        "There is no model yet: create it with the form in the middle. Then select a node, a flow or a component to edit it here.",
      );
      return;
    }
    if (!s) {
      el(
        "div",
        { class: "hint" },
        body,
        canvas.current === "components"
          ? "Click a component to edit its deployment, ports and links, or pick one from the library to add it."
          : "Click a node, a flow or a swimlane header to edit it; drag nodes from the palette.",
      );
      return;
    }
    this.drawBody(body, s);
  }
}

/** A labelled row. */
export function row(parent: HTMLElement, label: string): HTMLElement {
  const r = el("label", { class: "row" }, parent);
  el("span", { class: "key" }, r, label);
  return r;
}

export function button(parent: HTMLElement, name: string, text: string, fn: () => void, cls = ""): HTMLButtonElement {
  const b = el("button", { type: "button", name, class: cls }, parent, text);
  b.onclick = fn;
  return b;
}

/** A name and a Rename button: the server renames it and every reference to it; a refused name is
 * said at the field. */
export function renameForm(
  panel: Panel,
  body: HTMLElement,
  label: string,
  current: string,
  field: string,
  op: (name: string) => Op,
  selection: (name: string) => NonNullable<Selection>,
): void {
  const form = el("form", { class: "row rename", novalidate: "" }, body);
  el("span", { class: "key" }, form, label);
  const input = el(
    "input",
    {
      name: "rename",
      value: current,
      autocomplete: "off",
      spellcheck: "false",
      size: "14",
      "data-field": field,
      "data-label": label,
    },
    form,
  );
  input.title = "a new name: every reference to it in the model is renamed too";
  el("button", { type: "submit", name: "apply-rename" }, form, "Rename");
  form.onsubmit = async (ev) => {
    ev.preventDefault();
    const name = input.value.trim();
    if (!name || name === current) return;
    if (await panel.send([op(name)], form)) panel.select(selection(name));
  };
}
