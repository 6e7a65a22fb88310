// The Diagnostics panel: the compiler's problems, listed and marked on their nodes; a click shows
// the node (its diagram, centred).

import { $ } from "../../core/dom";
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
      li.textContent = d.text;
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
        if (li.dataset.file) bus.emit("file.fix", li.dataset.file);
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
