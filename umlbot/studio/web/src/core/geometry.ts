// The view's arithmetic: where a diagram is shown (pan x, y and zoom k, in canvas pixels), how a
// fit, a zoom at the pointer or a pan that shows an element move it, where a lane's header sits.
// Pure: no DOM (test/geometry.test.ts).

/** A diagram's view: diagram point p is drawn at canvas pixel (x + p.x * k, y + p.y * k). */
export interface View {
  x: number;
  y: number;
  k: number;
}
/** The canvas's size in pixels. */
export interface Size {
  W: number;
  H: number;
}
/** A drawing's extent (diagram units) and where a reader starts (`focus`). */
export interface Extent {
  width: number;
  height: number;
  focus?: { x: number; y: number };
}
/** A box by its edges, in canvas pixels. */
export interface Edges {
  left: number;
  top: number;
  right: number;
  bottom: number;
}

// Zoom levels: below LOD_MID the stats, values and guards are not drawn, below LOD_FAR not even
// the nodes' names (Canvas.apply). A diagram opens whole when that is readable (READABLE_K or
// more); a bigger one opens at OPEN_K on its start node, from the top: Fit (f) shows all of it.
export const LOD_MID = 0.45;
export const LOD_FAR = 0.3;
export const READABLE_K = 0.65; // 11 px texts at >= 7 px
export const OPEN_K = 0.8;
/** A short, wide diagram (the car's five motion lanes, its components on a laptop's canvas) opens
 * whole down to this zoom (11 px texts at 6 px) rather than cut at the right edge. */
export const WIDE_K = 0.55;
export const MIN_K = 0.02;
export const MAX_K = 8;

/** The whole diagram in the canvas; `readable`: when that is too small to read, a readable part
 * from the top (its width if that is readable, else OPEN_K, around the start node). */
export function fitView({ W, H }: Size, d: Extent, readable: boolean): View {
  const pad = 16;
  let k = Math.min((W - 2 * pad) / d.width, (H - 2 * pad) / d.height, 1.25);
  let y = (H - d.height * k) / 2;
  let x = (W - d.width * k) / 2;
  const kW = (W - 2 * pad) / d.width;
  const wideOnly = kW <= (H - 2 * pad) / d.height; // the width is what does not fit
  if (readable && k < READABLE_K && !(wideOnly && k >= WIDE_K)) {
    const kWidth = (W - 2 * pad) / d.width;
    // (a diagram cut at the bottom anyway opens no smaller than a big one: OPEN_K, so that a
    // narrower drawing of it, such as the car's `main` with its regions collapsed, is not
    // drawn smaller than the whole one)
    const tall = d.height * kWidth > H - 2 * pad;
    k = kWidth >= (tall ? OPEN_K : READABLE_K) ? Math.min(kWidth, 1) : OPEN_K;
    y = d.height * k > H - 2 * pad ? pad : (H - d.height * k) / 2;
    const w = d.width * k;
    if (w <= W - 2 * pad) x = (W - w) / 2;
    else {
      const fx = d.focus ? d.focus.x * k : 0;
      x = Math.min(pad, Math.max(W - pad - w, W / 2 - fx));
    }
  }
  k = Math.max(k, MIN_K);
  return { k, x, y };
}

/** After an edit: a diagram that fits the canvas (at its zoom, or zoomed out to >= 0.6) is shown whole. */
export function keptInView(view: View, { W, H }: Size, d: Extent): View {
  const v = { ...view };
  const pad = 16;
  const kFit = Math.min((W - 2 * pad) / d.width, (H - 2 * pad) / d.height);
  if (kFit < v.k && kFit >= 0.6) {
    // grown past the canvas but still readable whole: zoom out to show all of it
    v.x = (W - d.width * kFit) / 2;
    v.y = (H - d.height * kFit) / 2;
    v.k = kFit;
  }
  const w = d.width * v.k;
  const h = d.height * v.k;
  if (w <= W - 2 * pad) v.x = Math.min(Math.max(v.x, pad), W - pad - w);
  if (h <= H - 2 * pad) v.y = Math.min(Math.max(v.y, pad), H - pad - h);
  return v;
}

/** The view zoomed to `k` about canvas pixel (px, py): that point stays where it is. */
export function zoomedAt(view: View, px: number, py: number, k: number): View {
  return { x: px - ((px - view.x) * k) / view.k, y: py - ((py - view.y) * k) / view.k, k };
}

/** A zoom kept within what the page allows. */
export function clampZoom(k: number): number {
  return Math.min(MAX_K, Math.max(MIN_K, k));
}

/** The wheel's zoom factor for a wheel event's deltaY (lines when `lines`, else pixels). */
export function wheelZoom(k: number, deltaY: number, lines: boolean): number {
  const f = Math.exp(-deltaY * (lines ? 0.05 : 0.0015));
  return Math.min(MAX_K, Math.max(MIN_K, k * f));
}

/** The least pan that brings box `b` inside `c` with `pad` pixels to spare (the top-left wins when
 * it does not fit). */
export function panToShow(c: Edges, b: Edges, pad = 24): { dx: number; dy: number } {
  let dx = 0;
  let dy = 0;
  if (b.right > c.right - pad) dx = c.right - pad - b.right;
  if (b.left + dx < c.left + pad) dx = c.left + pad - b.left;
  if (b.bottom > c.bottom - pad) dy = c.bottom - pad - b.bottom;
  if (b.top + dy < c.top + pad) dy = c.top + pad - b.top;
  return { dx, dy };
}

/** A lane's place (diagram units): left edge, width, top, and its header's text width and height. */
export interface LaneBox {
  x: number;
  y: number;
  w: number;
  h: number;
  textW: number;
  headH: number;
}

/** Where a lane's header goes so that it stays on the lane's visible part: its texts' centre `cx`
 * (lane units) and how far down `dy` it moves (while the lane goes on below the canvas's top);
 * null when the lane is not in view. */
export function laneHeadPlace(lane: LaneBox, { x, y, k }: View, W: number): { cx: number; dy: number } | null {
  const left = Math.max(lane.x, -x / k);
  const right = Math.min(lane.x + lane.w, (W - x) / k);
  if (right <= left) return null;
  const half = lane.textW / 2 + 10;
  let cx = (left + right) / 2 - lane.x;
  cx = lane.w <= 2 * half ? lane.w / 2 : Math.min(Math.max(cx, half), lane.w - half);
  const dy = Math.max(0, Math.min(-y / k - lane.y, lane.h - lane.headH));
  return { cx, dy };
}
