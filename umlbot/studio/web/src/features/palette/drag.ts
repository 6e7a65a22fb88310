// Drag a node kind from the palette onto a swimlane (the lane under the pointer is outlined); a
// click adds it to the selected lane. The new node is selected, its first field ready to type.

import { el } from "../../core/dom";
import { findLane, selectedLane } from "../../core/selection";
import type { Studio } from "../../core/studio";
import type { NodeKind } from "../../model/types";
import { newNodeId } from "./names";

const CLICK_SLOP_PX = 4;

export function dragKind(studio: Studio, ev: PointerEvent, kind: NodeKind): void {
  const { bus, store, canvas } = studio;
  if (ev.button !== 0) return;
  ev.preventDefault();
  const ghost = el("div", { class: "drag-ghost", "data-kind": kind }, document.body, kind);
  let moved = false;
  const sx = ev.clientX;
  const sy = ev.clientY;
  const unmark = (): void => {
    for (const g of canvas.el.querySelectorAll("g.lane.drop")) g.classList.remove("drop");
  };
  const move = (e: PointerEvent): void => {
    if (Math.hypot(e.clientX - sx, e.clientY - sy) > CLICK_SLOP_PX) moved = true;
    ghost.style.left = `${e.clientX + 6}px`;
    ghost.style.top = `${e.clientY + 6}px`;
    ghost.hidden = !moved;
    const lane = laneAt(e.clientX, e.clientY);
    unmark();
    if (lane) laneG(studio, lane)?.classList.add("drop");
  };
  const up = (e: PointerEvent): void => {
    window.removeEventListener("pointermove", move);
    window.removeEventListener("pointerup", up);
    ghost.remove();
    unmark();
    const lane = moved
      ? laneAt(e.clientX, e.clientY)
      : selectedLane(store.edit?.selection ?? null, store.model, canvas.current);
    if (!lane) {
      if (!moved) {
        bus.request("notice.show", {
          kind: "hint",
          text: "Select a swimlane first (click its header or one of its nodes), or drag the node onto it.",
          hideAfterMs: 4000,
        });
      }
      return;
    }
    void addNode(studio, lane, kind);
  };
  window.addEventListener("pointermove", move);
  window.addEventListener("pointerup", up);
}

function laneG({ canvas }: Studio, lane: string): SVGGElement | null {
  return canvas.el.querySelector<SVGGElement>(
    `svg[data-diagram="${CSS.escape(canvas.current)}"] g.lane[data-lane="${CSS.escape(lane)}"]`,
  );
}

function laneAt(x: number, y: number): string | null {
  const hit = document.elementFromPoint(x, y);
  const g = hit?.closest?.("g.lane");
  return g ? g.getAttribute("data-lane") : null;
}

async function addNode({ bus, store }: Studio, lane: string, kind: NodeKind): Promise<void> {
  const l = findLane(store.model, lane);
  const id = newNodeId(kind, new Set(l?.nodes.map((n) => n.id) ?? []));
  const node: Record<string, unknown> = { id, kind };
  if (await bus.request("edit.send", [{ op: "add_node", lane, node }])) {
    store.edit!.selection = { type: "node", lane, id };
    bus.emit("props.render");
    bus.request("selection.highlight");
    bus.emit("props.focus", "input.code, input[name]");
  }
}
