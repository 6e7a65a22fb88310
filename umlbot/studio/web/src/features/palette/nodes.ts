// The palette on an activity diagram: the node kinds (the compiler's, in its order) to drag onto a
// swimlane or click into the selected one, and the form that adds a swimlane.

import { el } from "../../core/dom";
import type { Studio } from "../../core/studio";
import type { ModelView, Op } from "../../model/types";
import { addToSelected, dragKind } from "./drag";

/** Where the last swimlane was added (the form offers it again). */
export interface LaneFileChoice {
  file: string;
}

export function drawNodes(studio: Studio, p: HTMLElement, m: ModelView, choice: LaneFileChoice): void {
  const { bus, store } = studio;
  const edit = store.edit!;
  el("div", { class: "panel-title" }, p, "Nodes");
  el("div", { class: "hint" }, p, "drag onto a swimlane, or click to add to the selected one");
  const grid = el("div", { class: "kinds" }, p);
  // the node kinds are the compiler's (the server's library), in its order
  if (!edit.library) el("div", { class: "hint" }, grid, "loading…");
  for (const [kind, info] of Object.entries(edit.library?.node_kinds ?? {})) {
    const item = el(
      "div",
      {
        class: `item node-kind kind-${kind}`,
        "data-kind": kind,
        tabindex: "0",
        role: "button",
        title: `${info.doc ?? kind} (Enter adds it after the selected node)`,
      },
      grid,
    );
    el("i", { class: "icon" }, item);
    el("span", {}, item, kind);
    item.addEventListener("pointerdown", (ev) => dragKind(studio, ev, kind));
    item.addEventListener("keydown", (ev) => {
      if (ev.key !== "Enter" && ev.key !== " ") return;
      ev.preventDefault();
      ev.stopPropagation();
      addToSelected(studio, kind);
    });
  }
  el("div", { class: "panel-title" }, p, "Swimlanes");
  const form = el("form", { class: "add-lane" }, p);
  const lane = el(
    "input",
    {
      name: "lane-name",
      placeholder: "component or new activity",
      list: "lane-options",
      autocomplete: "off",
      "data-field": "lane",
    },
    form,
  );
  const dl = el("datalist", { id: "lane-options" }, form);
  const used = new Set(m.diagrams.flatMap((d) => d.lanes.map((l) => l.name)));
  for (const c of m.components) if (!used.has(c.name)) el("option", { value: c.name }, dl);
  const file = el(
    "select",
    { name: "lane-file", title: "where the lane is written", "aria-label": "file of the new swimlane" },
    form,
  );
  el("option", { value: "" }, file, "in a new file");
  // only the files a lane can be added to (the server says which: a `lanes:` list)
  for (const f of edit.info.lane_files ?? []) el("option", { value: f }, file, `in ${f}`);
  file.value = edit.info.lane_files?.includes(choice.file) ? choice.file : "";
  file.onchange = () => {
    choice.file = file.value;
  };
  el("button", { type: "submit", "data-action": "add-lane" }, form, "Add swimlane");
  el(
    "div",
    { class: "hint" },
    form,
    "a component's name runs on it; any other name is a virtual lane (a called activity)",
  );
  form.onsubmit = async (ev) => {
    ev.preventDefault();
    const name = lane.value.trim();
    if (!name) return;
    const op: Op = { op: "add_lane", lane: name };
    if (file.value) op.file = file.value;
    if (await bus.request("edit.send", [op], form)) {
      lane.value = "";
      const d = store.model?.diagrams.find((x) => x.lanes.some((l) => l.name === name));
      if (d) bus.emit("diagram.select", d.id);
      edit.selection = { type: "lane", lane: name };
      bus.emit("props.render");
    }
  };
}
