// A node's properties: its id (rename), the checker's problems on it, its kind's fields (a call or
// an expression with completion), its flows out (a decision's guards), Connect to…, Delete.

import { el } from "../../core/dom";
import { findLane } from "../../core/selection";
import { sameFile } from "../../model/paths";
import { codeInput } from "./code-input";
import { FLOW_TYPES, fieldText, GUARD_PLACEHOLDER, guardOf, nextLine, typed } from "./fields";
import { button, type Panel, renameForm, row } from "./panel";

export function nodeProps(panel: Panel, body: HTMLElement, laneName: string, id: string): void {
  const { bus, store } = panel.studio;
  const lane = findLane(store.model, laneName);
  const node = lane?.nodes.find((n) => n.id === id);
  if (!lane || !node) return;
  el("div", { class: "props-head" }, body, `${node.kind} · ${id}`);
  el("div", { class: "props-sub" }, body, `swimlane ${laneName} · ${lane.file}:${node.line}`);
  renameForm(
    panel,
    body,
    "id",
    id,
    "new_id",
    (v) => ({ op: "rename_node", lane: laneName, id, new_id: v }),
    (v) => ({ type: "node", lane: laneName, id: v }),
  );
  const marks = store.diagnostics.filter(
    (d) => sameFile(d.file, lane.file) && d.line >= node.line && d.line < nextLine(lane, node),
  );
  for (const d of marks) el("div", { class: `problem ${d.severity}`, "data-severity": d.severity }, body, d.text);
  // the kind's fields as the compiler defines them (the server's library)
  const library = panel.edit.library;
  if (!library) el("div", { class: "hint" }, body, "loading…");
  const fields = library?.node_kinds[node.kind]?.fields ?? {};
  for (const [field, info] of Object.entries(fields)) {
    if (info.type && FLOW_TYPES.has(info.type)) continue;
    const r = row(body, field + (info.required ? " *" : ""));
    const current = fieldText(node, field);
    const set = (text: string): void => {
      void panel.send([{ op: "set_node", lane: laneName, id, fields: { [field]: typed(field, text, info.type) } }]);
    };
    if (info.type === "expression") {
      // a call or an expression: edited with completion
      codeInput(panel, r, field, current, laneName, set);
    } else {
      const input = el("input", { name: field, value: current, autocomplete: "off", spellcheck: "false" }, r);
      if (info.doc) input.title = info.doc;
      input.onchange = () => set(input.value);
    }
  }
  // outgoing flows
  const out = lane.edges.filter((e) => e.source === id);
  if (out.length || node.kind !== "end") el("div", { class: "props-section" }, body, "Flows out");
  for (const e of out) {
    const r = el("div", { class: "flow", "data-target": e.target }, body);
    el("span", {}, r, `→ ${e.target}`);
    if (node.kind === "decision") {
      codeInput(
        panel,
        r,
        "guard",
        guardOf(node, e),
        laneName,
        (text) => {
          void panel.send([{ op: "set_guard", lane: laneName, source: id, target: e.target, guard: text.trim() }]);
        },
        { "data-target": e.target, placeholder: GUARD_PLACEHOLDER },
      );
    }
    const x = button(
      r,
      "disconnect",
      "×",
      () => void panel.send([{ op: "disconnect", lane: laneName, source: id, target: e.target }]),
      "small",
    );
    x.dataset.target = e.target;
    x.title = `remove the flow to ${e.target}`;
  }
  const actions = el("div", { class: "actions" }, body);
  if (node.kind !== "end") button(actions, "connect", "Connect to…", () => bus.emit("connect.start", laneName, id));
  button(actions, "remove", "Delete node", () => bus.emit("selection.delete"), "danger");
}
