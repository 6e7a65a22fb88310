// Drag a node kind from the palette onto a swimlane (the lane under the pointer is outlined); a
// click adds it to the selected lane. Dropped onto a flow, the new node goes between the flow's
// nodes; added with a node selected, it goes after that node, wired in. The new node is selected,
// its first field ready to type.

import { el } from "../../core/dom";
import { findLane, selectedLane } from "../../core/selection";
import type { Studio } from "../../core/studio";
import type { NodeKind } from "../../model/types";
import { newNodeId } from "./names";
import { type Flow, wiredIn } from "./wire";

const CLICK_SLOP_PX = 4;

export function dragKind(studio: Studio, ev: PointerEvent, kind: NodeKind): void {
  const { canvas } = studio;
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
    if (!moved) {
      addToSelected(studio, kind);
      return;
    }
    const lane = laneAt(e.clientX, e.clientY);
    if (lane) void addNode(studio, lane, kind, flowAt(e.clientX, e.clientY, lane));
  };
  window.addEventListener("pointermove", move);
  window.addEventListener("pointerup", up);
}

/** A click on a palette item, or Enter on it: the node goes to the selected lane (after the
 * selected node, wired in). */
export function addToSelected(studio: Studio, kind: NodeKind): void {
  const { bus, store, canvas } = studio;
  const lane = selectedLane(store.edit?.selection ?? null, store.model, canvas.current);
  if (!lane) {
    bus.request("notice.show", {
      kind: "hint",
      text: "Select a swimlane first (click its header or one of its nodes), or drag the node onto it.",
      hideAfterMs: 4000,
    });
    return;
  }
  void addNode(studio, lane, kind);
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

/** The flow of `lane` under the pointer (its wide, invisible hit line), or null. */
function flowAt(x: number, y: number, lane: string | null): Flow | null {
  const g = document
    .elementsFromPoint(x, y)
    .map((e) => e.closest?.("g.edge"))
    .find((e) => e && e.getAttribute("data-lane") === lane);
  return g ? { source: g.getAttribute("data-source") ?? "", target: g.getAttribute("data-target") ?? "" } : null;
}

async function addNode({ bus, store }: Studio, lane: string, kind: NodeKind, flow: Flow | null = null): Promise<void> {
  const l = findLane(store.model, lane);
  const id = newNodeId(kind, new Set(l?.nodes.map((n) => n.id) ?? []));
  // dropped onto a flow: between its nodes; else after the selected node of that lane
  const sel = store.edit?.selection;
  const after = sel?.type === "node" && sel.lane === lane ? sel.id : null;
  const ops = l ? wiredIn(l, kind, id, flow, after) : [{ op: "add_node", lane, node: { id, kind } }];
  if (await bus.request("edit.send", ops)) {
    store.edit!.selection = { type: "node", lane, id };
    bus.emit("props.render");
    bus.request("selection.highlight");
    bus.emit("props.focus", "input.code, input[name]");
  }
}
