// Follow the running robot, as a map app follows its user: the view pans (never zooms) to keep the
// node of the shown diagram that ran last in view when it leaves the canvas — checked at most every
// FOLLOW_EVERY_MS, a short pan eased, a long one at once. On by default (live and replay); a pan or
// zoom by hand, or taking hold of the diagram in the editor, turns it off; the toolbar's Follow
// button or the `l` key on again (`window.__studio.follow`, `followPans`).

import { $ } from "../../core/dom";
import type { Studio } from "../../core/studio";
import type { DiagramView } from "../../draw/render";
import {
  centredOn,
  FOLLOW_EVERY_MS,
  FOLLOW_NEW_LANE_MS,
  inView,
  isFar,
  lastRan,
  markerSpot,
  type Pan,
  panAt,
} from "./decide";

export function install({ bus, store, hooks, canvas, renderer, frames }: Studio): void {
  const btn = $<HTMLButtonElement>("#follow");
  // the node that ran last, when Follow is off and it is off the canvas: a marker on the edge
  // towards it; a click follows the robot again (and so shows it)
  const marker = $<HTMLButtonElement>("#running-marker");
  // (once a drawn frame: one node's box from its attributes, no layout)
  const markRunning = (): void => {
    if (hooks.follow) {
      marker.hidden = true;
      return;
    }
    const v = canvas.shown();
    const key = v?.view ? lastRan(store.model, canvas.current, store.live) : null;
    const g = key ? renderer.nodeEl(key)?.g : null;
    const box = g ? canvas.nodeBox(g) : null;
    const size = canvas.size();
    if (!v?.view || !g || !box || inView(v.view, box, size, 0)) {
      marker.hidden = true;
      return;
    }
    const spot = markerSpot(v.view, box, size);
    const name = g.getAttribute("data-node") ?? "";
    marker.hidden = false;
    marker.textContent = `${spot.arrow} running: ${name}`;
    marker.dataset.node = name;
    marker.title = `${name} ran last; it is off the canvas. Click to follow the robot again (l).`;
    marker.style.left = `${spot.left}px`;
    marker.style.top = `${spot.top}px`;
  };
  marker.addEventListener("pointerdown", (ev) => ev.stopPropagation());
  marker.addEventListener("click", () => set(true));
  let due = false; // nodes ran (or the view changed) since the last look
  let lookedAt = 0;
  let newLaneAt = 0;
  let pan: (Pan & { v: DiagramView }) | null = null;

  const set = (on: boolean): void => {
    hooks.follow = on;
    btn.setAttribute("aria-pressed", String(on));
    btn.title = on
      ? "Following the running robot: the view pans to the node that ran last (a pan or zoom by hand stops it; l)"
      : "Follow the running robot: pan to the node that ran last whenever it leaves the view (l)";
    pan = null;
    if (on) {
      due = true;
      lookedAt = 0;
      frames.schedule();
    }
  };

  /** One step, in the frame loop: the eased pan under way, else (at most every FOLLOW_EVERY_MS) a
   * look whether the node that ran last is still in view. */
  const step = (now: number): void => {
    if (canvas.drawPendingLane()) return;
    if (pan) {
      const p = pan;
      const at = panAt(p, now);
      if (p.v.view && canvas.shown() === p.v) {
        p.v.view.x = at.x;
        p.v.view.y = at.y;
        canvas.apply(p.v);
      }
      if (at.done || canvas.shown() !== p.v) pan = null;
      return;
    }
    if (!hooks.follow || !due || now - lookedAt < FOLLOW_EVERY_MS) return;
    due = false;
    lookedAt = now;
    const v = canvas.shown();
    const key = v?.view ? lastRan(store.model, canvas.current, store.live) : null;
    const g = key ? renderer.nodeEl(key)?.g : null;
    const box = g ? canvas.nodeBox(g) : null;
    if (!v?.view || !g || !box) return;
    const size = canvas.size();
    if (inView(v.view, box, size)) return;
    if (g.closest("g.lane")?.classList.contains("culled")) {
      if (now - newLaneAt < FOLLOW_NEW_LANE_MS) {
        due = true; // looked at again later
        return;
      }
      newLaneAt = now;
    }
    const to = centredOn(box, v.view.k, size);
    hooks.followPans += 1;
    if (isFar(v.view, to, size)) {
      v.view.x = to.x;
      v.view.y = to.y;
      canvas.apply(v, 1);
    } else pan = { v, x0: v.view.x, y0: v.view.y, x1: to.x, y1: to.y, t0: now };
  };

  btn.addEventListener("click", () => set(!hooks.follow));
  bus.on("follow.set", set);
  bus.on("follow.toggle", () => set(!hooks.follow));
  bus.on("follow.due", () => {
    due = true;
  });
  bus.on("frame.drawn", () => {
    const now = performance.now();
    step(now);
    markRunning();
  });
  bus.on("frame.busy", () => (pan !== null || canvas.lanesPending || (hooks.follow && due) ? true : undefined));
  set(true); // live and replay both start following
}
