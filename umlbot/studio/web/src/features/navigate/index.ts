// Pan and zoom by hand: drag to pan, the wheel zooms about the pointer, Fit (f) shows the whole
// diagram, a click on a call behaviour action opens the called activity. Doing any of it by hand
// stops following the robot (the view stays where the user put it).

import { $ } from "../../core/dom";
import { clampZoom, wheelZoom, zoomedAt } from "../../core/geometry";
import type { Studio } from "../../core/studio";
import { installEdges } from "./edges";
import { measureQuality } from "./quality";
import { reveal } from "./reveal";

const CLICK_SLOP_PX = 3;

export function install(studio: Studio): void {
  const { bus, store, hooks, canvas } = studio;
  const el = canvas.el;

  const fit = (): void => {
    const v = canvas.shown();
    if (v) canvas.fit(v, false);
  };
  $<HTMLButtonElement>("#fit").addEventListener("click", fit);
  installEdges(studio);
  bus.on("view.fit", fit);
  // by keys (features/keyboard): moved by hand, so the view stays where the user put it
  bus.on("view.pan", (dx, dy) => {
    const v = canvas.shown();
    if (!v?.view) return;
    bus.emit("follow.set", false);
    v.view.x += dx;
    v.view.y += dy;
    canvas.apply(v);
  });
  bus.on("view.zoom", (factor) => {
    const v = canvas.shown();
    if (!v?.view) return;
    bus.emit("follow.set", false);
    const { W, H } = canvas.size();
    v.view = zoomedAt(v.view, W / 2, H / 2, clampZoom(v.view.k * factor));
    canvas.apply(v);
  });
  bus.on("view.reveal", (lane, node) => reveal(studio, lane, node));
  hooks.reveal = (lane, node) => reveal(studio, lane, node);
  hooks.quality = (id) => {
    const v = canvas.views.get(id);
    return v ? measureQuality(v.viewport) : null;
  };

  el.addEventListener(
    "wheel",
    (ev) => {
      const v = canvas.shown();
      if (!v?.view) return;
      ev.preventDefault();
      const r = el.getBoundingClientRect();
      const k = wheelZoom(v.view.k, ev.deltaY, ev.deltaMode === 1);
      bus.emit("follow.set", false); // zoomed by hand: the view stays where the user put it
      v.view = zoomedAt(v.view, ev.clientX - r.left, ev.clientY - r.top, k);
      canvas.apply(v);
    },
    { passive: false },
  );

  let drag: { x: number; y: number; vx: number; vy: number; moved: boolean; id: number } | null = null;
  el.addEventListener("pointerdown", (ev) => {
    if (bus.request("canvas.press", ev)) {
      bus.emit("follow.set", false); // working on the diagram: it must not move away under the pointer
      return;
    }
    const v = canvas.shown();
    if (!v?.view || ev.button !== 0) return;
    drag = { x: ev.clientX, y: ev.clientY, vx: v.view.x, vy: v.view.y, moved: false, id: ev.pointerId };
  });
  el.addEventListener("pointermove", (ev) => {
    const v = canvas.shown();
    if (!drag || !v?.view || ev.pointerId !== drag.id) return;
    const dx = ev.clientX - drag.x;
    const dy = ev.clientY - drag.y;
    if (!drag.moved && Math.hypot(dx, dy) > CLICK_SLOP_PX) {
      drag.moved = true;
      bus.emit("follow.set", false); // panned by hand: the view stays where the user put it
      el.setPointerCapture(ev.pointerId);
      el.classList.add("dragging");
    }
    if (drag.moved) {
      v.view.x = drag.vx + dx;
      v.view.y = drag.vy + dy;
      canvas.apply(v);
    }
  });
  const endDrag = (ev: PointerEvent): void => {
    if (!drag || ev.pointerId !== drag.id) return;
    const wasClick = !drag.moved;
    drag = null;
    el.classList.remove("dragging");
    if (wasClick) {
      // A click on a call behaviour action opens the called activity.
      const g = (ev.target as Element).closest?.("g.node.calls");
      const lane = g?.getAttribute("data-calls");
      const diagram = lane ? store.laneDiagram.get(lane) : undefined;
      if (diagram) bus.emit("diagram.select", diagram);
    }
  };
  el.addEventListener("pointerup", endDrag);
  el.addEventListener("pointercancel", endDrag);
}
