// The palette on the components diagram (or with no model): the component library, grouped by
// kind, each implementation with its features; a click offers it in the properties to be added.

import { el } from "../../core/dom";
import type { Studio } from "../../core/studio";
import { features, signatureText } from "../../model/library";
import type { ImplInfo } from "../../model/types";

export function drawLibrary({ bus, store }: Studio, p: HTMLElement): void {
  const edit = store.edit!;
  el("div", { class: "panel-title" }, p, "Component library");
  if (edit.info.empty) {
    // browsable before there is a model; adding a part needs the model it goes into
    el(
      "div",
      { class: "hint", "data-hint": "no-model" },
      p,
      "There is no model yet: create it first (the form in the middle). Then click a part here to add it to the model.",
    );
  }
  const library = edit.library;
  if (!library) {
    el("div", { class: "hint" }, p, "loading…");
    return;
  }
  const byKind = new Map<string, ImplInfo[]>();
  for (const impl of library.implementations) {
    const list = byKind.get(impl.kind) ?? [];
    list.push(impl);
    byKind.set(impl.kind, list);
  }
  for (const [kind, impls] of byKind) {
    const group = el("div", { class: "group", "data-group": kind }, p);
    el("div", { class: "group-title" }, group, kind);
    for (const impl of impls) {
      const item = el(
        "div",
        { class: "item impl", "data-impl": impl.id, "data-kind": impl.kind, tabindex: "0", role: "button" },
        group,
      );
      el("b", {}, item, impl.id);
      if (impl.service) el("small", {}, item, ` · ${impl.service}`);
      const list = el("div", { class: "features" }, item);
      for (const [f, info] of Object.entries(features(impl, library))) {
        el("div", { "data-feature": f }, list, info ? signatureText(f, info) : f);
      }
      if (impl.aliases.length) el("div", { class: "aliases" }, item, `seeds: ${impl.aliases.join(", ")}`);
      item.title = impl.title ?? impl.doc ?? `${impl.kind} ${impl.id}`;
      item.onclick = () => {
        edit.selection = { type: "new-component", impl: impl.id };
        bus.emit("props.render");
        bus.emit("props.focus", '[name="name"]');
      };
      item.onkeydown = (ev) => {
        if (ev.key !== "Enter" && ev.key !== " ") return;
        ev.preventDefault();
        ev.stopPropagation();
        item.click();
      };
    }
  }
}
