// Drag a node or a component: a click selects it, a drag moves it (its place is kept in the
// layout file: `set_layout`). The drawing moves at once; the model is drawn again with the new
// place while the edit goes to the studio.

import type { Studio } from "../../core/studio";
import { droppedAt } from "./place";

const CLICK_SLOP_PX = 4;

/** Follow the pointer from `ev` until it is released: `moving(dx, dy)` as it moves (screen px,
 * once past the click slop), then `done(moved, dx, dy, up)`. */
function track(
  ev: PointerEvent,
  moving: (dx: number, dy: number) => void,
  done: (moved: boolean, dx: number, dy: number, up: PointerEvent) => void,
): void {
  const sx = ev.clientX;
  const sy = ev.clientY;
  let moved = false;
  const move = (e: PointerEvent): void => {
    if (!moved && Math.hypot(e.clientX - sx, e.clientY - sy) > CLICK_SLOP_PX) moved = true;
    if (moved) moving(e.clientX - sx, e.clientY - sy);
  };
  const up = (e: PointerEvent): void => {
    window.removeEventListener("pointermove", move);
    window.removeEventListener("pointerup", up);
    done(moved, e.clientX - sx, e.clientY - sy, e);
  };
  window.addEventListener("pointermove", move);
  window.addEventListener("pointerup", up);
}

const scale = ({ canvas }: Studio): number => canvas.shown()?.view?.k ?? 1;

/** Click selects a node (a click on a call's rake opens the called activity); dragging moves it. */
export function dragNode(studio: Studio, ev: PointerEvent, g: SVGGElement, lane: string, id: string): void {
  const { bus, store, canvas } = studio;
  const k = scale(studio);
  track(
    ev,
    (dx, dy) => g.setAttribute("transform", `translate(${dx / k},${dy / k})`),
    (moved, dx, dy, up) => {
      const edit = store.edit!;
      if (!moved) {
        const rake = (up.target as Element).closest?.(".rake");
        const called = g.getAttribute("data-calls");
        if (rake && called) {
          const d = store.model?.diagrams.find((x) => x.lanes.some((l) => l.name === called));
          if (d) bus.emit("diagram.select", d.id);
          return;
        }
        edit.selection = { type: "node", lane, id };
        bus.emit("props.render");
        bus.request("selection.highlight");
        return;
      }
      const diagram = canvas.current;
      const pos = { ...(edit.positions[diagram] ?? {}) };
      pos[`${lane}/${id}`] = droppedAt(Number(g.getAttribute("data-x")), Number(g.getAttribute("data-y")), dx, dy, k);
      edit.positions = { ...edit.positions, [diagram]: pos };
      edit.selection = { type: "node", lane, id };
      bus.emit("model.relayout");
      void bus.request("edit.send", [{ op: "set_layout", diagram, positions: pos }]);
    },
  );
}

/** Click selects a component; dragging moves it. */
export function dragComponent(studio: Studio, ev: PointerEvent, g: SVGGElement): void {
  const { bus, store } = studio;
  const name = g.getAttribute("data-component")!;
  const k = scale(studio);
  track(
    ev,
    (dx, dy) => g.setAttribute("transform", `translate(${dx / k},${dy / k})`),
    (moved, dx, dy) => {
      const edit = store.edit!;
      edit.selection = { type: "component", name };
      if (!moved) {
        bus.emit("props.render");
        bus.request("selection.highlight");
        return;
      }
      const pos = { ...(edit.positions.components ?? {}) };
      pos[name] = droppedAt(Number(g.getAttribute("data-x")), Number(g.getAttribute("data-y")), dx, dy, k);
      edit.positions = { ...edit.positions, components: pos };
      bus.emit("model.relayout");
      void bus.request("edit.send", [{ op: "set_layout", diagram: "components", positions: pos }]);
      bus.emit("props.render");
    },
  );
}
