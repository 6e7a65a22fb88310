// The canvas: the drawings (one per diagram), the one shown, and each drawing's view (pan and
// zoom) applied to its SVG with the level of detail, the lanes off the canvas and the sticky lane
// headers that go with it (after diagram-js's lib/core/Canvas.js).

import type { DiagramView } from "../draw/render";
import { fitView, keptInView, LOD_FAR, LOD_MID, panToShow, type Size } from "./geometry";
import { type Box, Lanes } from "./lanes";

export class Canvas {
  readonly el: HTMLDivElement;
  /** The drawings by diagram id (written by the diagrams feature). */
  views = new Map<string, DiagramView>();
  /** The diagram shown (written by the diagrams feature). */
  current = "";
  private lanes = new Lanes();
  /** A view whose lanes are still to be drawn, one a frame (after a jump of the view). */
  private pending: DiagramView | null = null;
  private width = 0;
  private height = 0;
  /** Called after each view change of a drawing (the lane-edge hints follow it). */
  readonly applied: ((v: DiagramView) => void)[] = [];

  constructor(el: HTMLDivElement) {
    this.el = el;
    // The size, kept up to date by a ResizeObserver: reading clientWidth after the drawing changed
    // would force the browser to lay out the whole diagram there and then.
    new ResizeObserver(() => {
      this.width = el.clientWidth;
      this.height = el.clientHeight;
    }).observe(el);
  }

  size(): Size {
    if (!this.width) {
      this.width = this.el.clientWidth;
      this.height = this.el.clientHeight;
    }
    return { W: this.width || 800, H: this.height || 600 };
  }

  /** The drawing shown, once it is drawn. */
  shown(): DiagramView | undefined {
    return this.views.get(this.current);
  }

  /** Show `v` at its view; `newLanes`: how many lanes not drawn so far it may draw now (the others
   * on the next frames: `drawPendingLane`). */
  apply(v: DiagramView, newLanes = Infinity): void {
    if (!v.view) return;
    v.viewport.setAttribute("transform", `translate(${v.view.x},${v.view.y}) scale(${v.view.k})`);
    // Level of detail: text too small to read is not drawn (keeps big diagrams fast).
    const k = v.view.k;
    v.svg.classList.toggle("lod-mid", k < LOD_MID);
    v.svg.classList.toggle("lod-far", k < LOD_FAR);
    const { W } = this.size();
    this.pending = this.lanes.cull(v, W, newLanes) ? v : null;
    this.lanes.stickHeads(v, W);
    for (const f of this.applied) f(v);
  }

  /** The swimlanes of `v`: name and place (diagram units), from their attributes (no layout). */
  laneSpans(v: DiagramView): { name: string; x: number; w: number }[] {
    return this.lanes.spansOf(v);
  }

  /** Lanes of the shown view are still to be drawn (`drawPendingLane` on the next frames). */
  get lanesPending(): boolean {
    return this.pending !== null;
  }

  /** Draw one more of the lanes still to be drawn; false when there were none. */
  drawPendingLane(): boolean {
    const v = this.pending;
    if (!v) return false;
    const { W } = this.size();
    this.pending = this.shown() === v && this.lanes.cull(v, W, 1) ? v : null;
    this.lanes.stickHeads(v, W);
    return true;
  }

  /** Show the whole diagram; `readable`: when that is too small to read, a readable part from the top. */
  fit(v: DiagramView, readable = true): void {
    // measured now: the size the observer last said may be older than the page's layout (a
    // diagram opened at a stale, wider size was cut at the right edge)
    this.width = this.el.clientWidth || this.width;
    this.height = this.el.clientHeight || this.height;
    v.view = fitView(this.size(), v, readable);
    this.apply(v);
  }

  /** After an edit: a diagram that fits the canvas is shown whole (not applied yet). */
  keepInView(v: DiagramView): void {
    if (v.view) v.view = keptInView(v.view, this.size(), v);
  }

  /** Pan (no zoom) so that `el` is inside the canvas. */
  showElement(v: DiagramView, el: Element): void {
    if (!v.view) return;
    this.uncull(el);
    const box = this.lanes.nodeBox(el);
    let c: { left: number; top: number; right: number; bottom: number };
    let b: { left: number; top: number; right: number; bottom: number };
    if (box) {
      // a node: where it is from its attributes (measuring it would lay the diagram out now)
      const { W, H } = this.size();
      const k = v.view.k;
      c = { left: 0, top: 0, right: W, bottom: H };
      b = {
        left: v.view.x + box.x * k,
        top: v.view.y + box.y * k,
        right: v.view.x + (box.x + box.w) * k,
        bottom: v.view.y + (box.y + box.h) * k,
      };
    } else {
      c = this.el.getBoundingClientRect();
      b = el.getBoundingClientRect();
    }
    const { dx, dy } = panToShow(c, b);
    if (!dx && !dy) return;
    v.view.x += dx;
    v.view.y += dy;
    this.apply(v);
  }

  /** A node's box in diagram units (from attributes: no layout); null for anything else. */
  nodeBox(el: Element): Box | null {
    return this.lanes.nodeBox(el);
  }

  /** Draw the lane of `el` (not drawn when it was off the canvas) so that it can be measured. */
  uncull(el: Element): void {
    el.closest("g.lane")?.classList.remove("culled");
  }
}
