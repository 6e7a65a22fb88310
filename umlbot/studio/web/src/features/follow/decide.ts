// Follow's decisions: which node ran last, whether it is in view, where the view goes to show it,
// and the eased pan there. Pure (test/follow.test.ts).

import type { Size, View } from "../../core/geometry";
import { nodeKey, type StudioState } from "../../model/state";
import type { ModelView } from "../../model/types";

export const FOLLOW_EVERY_MS = 250; // a look whether the node is in view, at most this often
export const FOLLOW_PAN_MS = 300; // a short pan is eased over this
export const FOLLOW_MARGIN = 32; // px the node keeps from the canvas's edges
// A pan to a lane not drawn now (off the canvas: culled) draws it, a layout of its every node:
// at most one such pan a second (under thousands of events/s the last node jumps between lanes).
export const FOLLOW_NEW_LANE_MS = 1000;

interface Box {
  x: number;
  y: number;
  w: number;
  h: number;
}

/** The node of diagram `id` that ran last (the latest of its lanes' current nodes), or null. */
export function lastRan(model: ModelView | null, id: string, state: StudioState): string | null {
  let best: string | null = null;
  let bestIdx = -1;
  for (const lane of model?.diagrams.find((d) => d.id === id)?.lanes ?? []) {
    const now = state.trails.get(lane.name)?.[0];
    if (now === undefined) continue;
    const key = nodeKey(lane.name, now);
    const idx = state.nodes.get(key)?.lastIdx ?? -1;
    if (idx > bestIdx) {
      bestIdx = idx;
      best = key;
    }
  }
  return best;
}

/** Box `box` (diagram units) is drawn inside the canvas with `margin` px to spare. */
export function inView({ x, y, k }: View, box: Box, { W, H }: Size, margin = FOLLOW_MARGIN): boolean {
  const left = x + box.x * k;
  const top = y + box.y * k;
  return left >= margin && top >= margin && left + box.w * k <= W - margin && top + box.h * k <= H - margin;
}

/** The pan that centres `box` (a node near an edge would leave again at once). */
export function centredOn(box: Box, k: number, { W, H }: Size): { x: number; y: number } {
  return { x: W / 2 - (box.x + box.w / 2) * k, y: H / 2 - (box.y + box.h / 2) * k };
}

/** A pan this long is made at once, not eased (gliding over lanes in between would draw each of
 * them on the way). */
export function isFar(from: { x: number; y: number }, to: { x: number; y: number }, { W, H }: Size): boolean {
  return Math.hypot(to.x - from.x, to.y - from.y) > 0.75 * Math.max(W, H);
}

export interface Pan {
  x0: number;
  y0: number;
  x1: number;
  y1: number;
  t0: number;
}

/** Where an eased pan is at time `now`, and whether it is over. */
export function panAt(p: Pan, now: number): { x: number; y: number; done: boolean } {
  const t = Math.min(1, (now - p.t0) / FOLLOW_PAN_MS);
  const e = t * t * (3 - 2 * t);
  return { x: p.x0 + (p.x1 - p.x0) * e, y: p.y0 + (p.y1 - p.y0) * e, done: t >= 1 };
}

/** Where the marker of a node off the canvas goes: on the canvas's edge towards the node (px,
 * clamped inside the canvas), with an arrow that points at it. */
export function markerSpot({ x, y, k }: View, box: Box, { W, H }: Size): { left: number; top: number; arrow: string } {
  const cx = x + (box.x + box.w / 2) * k;
  const cy = y + (box.y + box.h / 2) * k;
  const pad = 24;
  const left = Math.min(Math.max(cx, pad), W - pad);
  const top = Math.min(Math.max(cy, pad), H - pad);
  const dx = cx < 0 ? -1 : cx > W ? 1 : 0;
  const dy = cy < 0 ? -1 : cy > H ? 1 : 0;
  const arrow = dy < 0 ? "↑" : dy > 0 ? "↓" : dx < 0 ? "←" : "→";
  return { left, top, arrow };
}
