// Which swimlanes are off the canvas to the left and to the right, and where a pan to the next
// one goes. Pure (test/navigate.test.ts).

import type { View } from "../../core/geometry";

export interface Span {
  name: string;
  x: number;
  w: number;
}

/** A lane counts as off the canvas when less than this part of it shows. */
const SHOWN_PART = 0.5;
const PAD = 16;

export interface Offside {
  /** lanes mostly off the canvas to the left, the nearest first */
  left: Span[];
  /** lanes mostly off the canvas to the right, the nearest first */
  right: Span[];
}

export function offside(spans: Span[], view: View, W: number): Offside {
  const left: Span[] = [];
  const right: Span[] = [];
  for (const s of spans) {
    const a = view.x + s.x * view.k;
    const b = a + s.w * view.k;
    const shown = Math.max(0, Math.min(b, W) - Math.max(a, 0));
    if (shown >= SHOWN_PART * Math.min(b - a, W)) continue; // (a lane wider than the canvas: half the canvas)
    if ((a + b) / 2 < W / 2) left.push(s);
    else right.push(s);
  }
  left.sort((p, q) => q.x - p.x);
  right.sort((p, q) => p.x - q.x);
  return { left, right };
}

/** The view's x that brings lane `s` into the canvas from side `side`: its far edge at the canvas's
 * edge (or its near edge, when it is wider than the canvas). */
export function panTo(s: Span, view: View, W: number, side: "left" | "right"): number {
  const w = s.w * view.k;
  if (w > W - 2 * PAD) return PAD - s.x * view.k; // wider than the canvas: its start
  return side === "right" ? W - PAD - (s.x + s.w) * view.k : PAD - s.x * view.k;
}

/** What a hint says: "2 more lanes: TurnRight, Stop" (names cut after three). */
export function hintText(lanes: Span[]): string {
  const names = lanes.slice(0, 3).map((s) => s.name);
  const more = lanes.length > 3 ? `, +${lanes.length - 3}` : "";
  return `${lanes.length} more lane${lanes.length === 1 ? "" : "s"}: ${names.join(", ")}${more}`;
}
