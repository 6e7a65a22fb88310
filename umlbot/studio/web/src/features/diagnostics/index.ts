// The Diagnostics panel: the compiler's problems, listed and marked on their nodes; a click shows
// the node (its diagram, centred).

import { $, el } from "../../core/dom";
import type { Studio } from "../../core/studio";
import { nodeKey } from "../../model/state";
import type { Diagnostic } from "../../model/types";
import { changedMarks, nodeAtLine, nodeNamed, strongerMark } from "./locate";

export function install({ bus, store, renderer }: Studio): void {
  const listEl = $<HTMLUListElement>("#diagnostics");
  const countEl = $<HTMLElement>("#diagnostics-count");

  const set = (list: Diagnostic[]): void => {
    store.diagnostics = list;
    listEl.replaceChildren();
    const before = new Map(renderer.marks);
    renderer.marks.clear();
    for (const d of list) {
      const li = document.createElement("li");
      li.className = d.severity;
      // the problem in a modeller's words, where it is (a click shows that line of the file), and
      // the checker's own message as `umlbot check` prints it
      if (d.plain && d.plain !== d.message) el("span", { class: "plain" }, li, d.plain);
      if (d.relpath && d.line > 0) {
        const where = el("button", { type: "button", class: "where", title: "Show this line of the file" }, li);
        where.textContent = `${d.relpath}:${d.line}`;
        where.addEventListener("click", (ev) => {
          ev.stopPropagation();
          bus.emit("file.show", d.relpath!, d.line, d.column, d.plain ?? d.message);
        });
      }
      el("span", { class: "text" }, li, d.text);
      listEl.append(li);
      const at =
        d.lane !== undefined
          ? nodeNamed(store.laneDiagram, store.index, d.lane ?? "", d.node ?? "")
          : nodeAtLine(store.model, d.file, d.line);
      if (at) {
        const key = nodeKey(at.lane, at.node);
        renderer.marks.set(key, strongerMark(renderer.marks.get(key), d));
        li.dataset.diagram = at.diagram;
        li.dataset.lane = at.lane;
        li.dataset.node = at.node;
      } else if (d.lane && store.laneDiagram.has(d.lane)) {
        li.dataset.diagram = store.laneDiagram.get(d.lane)!; // a problem of the lane itself: its diagram
      }
      if (!at && d.relpath && d.message.startsWith("invalid YAML")) li.dataset.file = d.relpath; // its text opens
      li.addEventListener("click", () => {
        if (li.dataset.file) bus.emit("file.show", li.dataset.file, d.line, d.column, d.plain ?? d.message);
        if (!li.dataset.diagram) return;
        bus.emit("diagram.select", li.dataset.diagram);
        if (li.dataset.lane && li.dataset.node) bus.emit("view.reveal", li.dataset.lane, li.dataset.node);
      });
    }
    countEl.textContent = String(list.length);
    bus.emit("diagnostics.changed", list);
    for (const key of changedMarks(before, renderer.marks)) store.live.dirtyNodes.add(key);
  };

  bus.on("diagnostics.set", set);
}
