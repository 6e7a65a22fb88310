// A flow's properties (a decision's output: its guard) and a swimlane's (a virtual lane's name).

import { el } from "../../core/dom";
import { findLane } from "../../core/selection";
import { codeInput } from "./code-input";
import { GUARD_PLACEHOLDER, guardOf } from "./fields";
import { button, type Panel, renameForm, row } from "./panel";

export function edgeProps(panel: Panel, body: HTMLElement, laneName: string, source: string, target: string): void {
  const { bus, store } = panel.studio;
  const lane = findLane(store.model, laneName);
  const e = lane?.edges.find((x) => x.source === source && x.target === target);
  if (!lane || !e) return;
  const src = lane.nodes.find((n) => n.id === source);
  el("div", { class: "props-head" }, body, `flow ${source} → ${target}`);
  el("div", { class: "props-sub" }, body, `swimlane ${laneName}`);
  if (src?.kind === "decision") {
    const r = row(body, "guard");
    codeInput(
      panel,
      r,
      "guard",
      src ? guardOf(src, e) : e.label,
      laneName,
      (text) => {
        void panel.send([{ op: "set_guard", lane: laneName, source, target, guard: text.trim() }]);
      },
      { "data-target": target, placeholder: GUARD_PLACEHOLDER },
    );
    el("div", { class: "hint" }, body, "a condition, or else");
  }
  const actions = el("div", { class: "actions" }, body);
  button(actions, "remove", "Delete flow", () => bus.emit("selection.delete"), "danger");
}

export function laneProps(panel: Panel, body: HTMLElement, laneName: string): void {
  const { bus, store } = panel.studio;
  const lane = findLane(store.model, laneName);
  if (!lane) return;
  el("div", { class: "props-head" }, body, `swimlane ${laneName}`);
  el(
    "div",
    { class: "props-sub" },
    body,
    `${lane.virtual ? "virtual: an activity that other lanes call" : `runs on the component ${lane.component ?? laneName}`} · ${lane.file}:${lane.line}`,
  );
  if (lane.virtual) {
    renameForm(
      panel,
      body,
      "name",
      laneName,
      "new_name",
      (v) => ({ op: "rename_lane", lane: laneName, new_name: v }),
      (v) => ({ type: "lane", lane: v }),
    );
  } else {
    el(
      "div",
      { class: "hint", "data-hint": "rename" },
      body,
      `Its name is the component's: rename the component ${laneName} to rename it.`,
    );
  }
  el("div", { class: "hint" }, body, "Drag nodes from the palette into it, or click a node kind to add it here.");
  const actions = el("div", { class: "actions" }, body);
  button(actions, "remove-lane", "Delete swimlane", () => bus.emit("selection.delete"), "danger");
}
