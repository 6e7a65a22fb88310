// Connect and drag on the canvas (edit mode): a press on a node drags or selects it, or — after
// "Connect to…" — connects the node chosen before to it; a drag from a node's output port to
// another node connects them (a decision then asks for the new way's guard); a press on a component drags or selects
// it; on a flow or a swimlane's header, selects it. Anything else is the canvas's (panning).

import { findLane, type Selection } from "../../core/selection";
import type { Studio } from "../../core/studio";
import { isRegionId } from "../../draw/regions";
import type { Op } from "../../model/types";
import { dragComponent, dragNode } from "./move";
import { dragFlow } from "./wire";

export function install(studio: Studio): void {
  const { bus, store, canvas } = studio;
  /** the node a flow is being drawn from ("Connect to…", until the next press or Esc) */
  let from: { lane: string; id: string } | null = null;

  const cancel = (): void => {
    from = null;
    canvas.el.classList.remove("connecting");
  };

  const select = (sel: Selection): void => {
    store.edit!.selection = sel;
    bus.emit("props.render");
    bus.request("selection.highlight");
  };

  /** The node chosen by "Connect to…", ending that mode. */
  const takeFrom = (): { lane: string; id: string } => {
    const start = from!;
    cancel();
    bus.emit("notice.hide", "hint");
    return start;
  };

  /** True when a flow from `sourceLane` may end in `targetLane`; else says why. */
  const sameLane = (sourceLane: string, targetLane: string): boolean => {
    if (sourceLane === targetLane) return true;
    bus.request("notice.show", {
      kind: "error",
      text: "A flow stays inside its swimlane: connect nodes of the same lane.",
      hideAfterMs: 5000,
    });
    return false;
  };

  const connect = async (lane: string, source: string, target: string): Promise<void> => {
    // a decision's first output is its else; the server writes any other with an empty guard,
    // which the checker reports on the decision until it is typed here
    const op: Op = { op: "connect", lane, source, target };
    const src = findLane(store.model, lane)?.nodes.find((n) => n.id === source);
    if (await bus.request("edit.send", [op])) {
      select(src?.kind === "decision" ? { type: "edge", lane, source, target } : { type: "node", lane, id: source });
      if (src?.kind === "decision") bus.emit("props.focus", '[name="guard"]', true);
    }
  };

  /** A press on the canvas in edit mode; true when taken (no panning). */
  const press = (ev: PointerEvent): boolean | undefined => {
    if (!store.edit) return undefined;
    if (ev.button !== 0) return false;
    const target = ev.target as Element;
    const nodeG = target.closest?.("g.node");
    const compG = target.closest?.("g.component");
    const edgeG = target.closest?.("g.edge");
    const header = target.closest?.(".lane-header, .lane-title, .lane-sub");
    if (nodeG) {
      const lane = nodeG.getAttribute("data-lane")!;
      const id = nodeG.getAttribute("data-node")!;
      if (target.classList.contains("port-out") && !from) {
        // a flow drawn from the node's output port: dropped on a node of its lane, it connects them
        dragFlow(canvas.el, ev, target, (to) => {
          // (a collapsed region's box is no node of the model: features/regions)
          if (to && sameLane(lane, to.lane) && to.id !== id && !isRegionId(to.id)) void connect(lane, id, to.id);
        });
        return true;
      }
      if (from) {
        const start = takeFrom();
        if (sameLane(start.lane, lane)) void connect(lane, start.id, id);
        return true;
      }
      dragNode(studio, ev, nodeG as SVGGElement, lane, id);
      return true;
    }
    if (compG) {
      dragComponent(studio, ev, compG as SVGGElement);
      return true;
    }
    if (edgeG && target.classList.contains("hit")) {
      select({
        type: "edge",
        lane: edgeG.getAttribute("data-lane")!,
        source: edgeG.getAttribute("data-source")!,
        target: edgeG.getAttribute("data-target")!,
      });
      return true;
    }
    if (header) {
      const lane = header.closest("g.lane")?.getAttribute("data-lane");
      if (lane) {
        select({ type: "lane", lane });
        return true;
      }
    }
    if (from) cancel();
    return false;
  };

  /** Enter or space on a focused node, lane header or component (keyboard): as a click on it —
   * after "Connect to…" it connects; else it selects it and goes to its first field. */
  const activate = (target: Element): boolean | undefined => {
    if (!store.edit) return undefined;
    const nodeG = target.closest("g.node");
    if (nodeG) {
      const lane = nodeG.getAttribute("data-lane")!;
      const id = nodeG.getAttribute("data-node")!;
      if (from) {
        const start = takeFrom();
        if (sameLane(start.lane, lane) && start.id !== id) void connect(lane, start.id, id);
        return true;
      }
      select({ type: "node", lane, id });
    } else if (target.closest("g.component")) {
      select({ type: "component", name: target.closest("g.component")!.getAttribute("data-component")! });
    } else if (target.closest("g.lane-head")) {
      const lane = target.closest("g.lane")?.getAttribute("data-lane");
      if (!lane) return undefined;
      select({ type: "lane", lane });
    } else return undefined;
    bus.emit("props.focus", "input, select");
    return true;
  };

  bus.on("canvas.press", press);
  bus.on("canvas.activate", activate);
  bus.on("connect.cancel", cancel);
  bus.on("connect.start", (lane, id) => {
    from = { lane, id };
    canvas.el.classList.add("connecting");
    bus.request("notice.show", {
      kind: "hint",
      text: `Click the node that follows ${id} (or Tab to it and press Enter; Esc cancels).`,
      hideAfterMs: 5000,
    });
  });
}
