// The swimlanes of a shown drawing, read from their attributes only (reading the layout would make
// the browser lay the whole diagram out there and then): where a lane and a node are, which lanes
// are off the canvas (not drawn), and each lane's header kept on the lane's visible part.

import type { DiagramView } from "../draw/render";
import { laneHeadPlace, type View } from "./geometry";

interface LaneSpan {
  t: string;
  x: number;
  y: number;
  w: number;
  bodyY: number;
  bg: Element | null;
  head: Element | null;
  texts: Element[];
  tw: number;
  headH: number;
}

/** A node's box in diagram units. */
export interface Box {
  x: number;
  y: number;
  w: number;
  h: number;
}

export class Lanes {
  private spans = new WeakMap<Element, LaneSpan>();
  private headAt = new WeakMap<Element, string>();

  /** A lane's place (diagram units) from its attributes: no layout. */
  private spanOf(g: Element): LaneSpan {
    const t = g.getAttribute("transform") ?? "";
    let span = this.spans.get(g);
    if (!span || span.t !== t) {
      const m = /translate\(([-\d.e]+)[ ,]+([-\d.e]+)/.exec(t);
      const body = /translate\([-\d.e]+[ ,]+([-\d.e]+)/.exec(
        g.querySelector(".lane-body")?.getAttribute("transform") ?? "",
      );
      const bg = g.querySelector(".lane-bg");
      const head = g.querySelector(".lane-head");
      span = {
        t,
        x: m ? Number(m[1]) : 0,
        y: m ? Number(m[2]) : 0,
        w: Number(bg?.getAttribute("width") ?? 0),
        bodyY: body ? Number(body[1]) : 0,
        bg,
        head,
        texts: head ? [...head.querySelectorAll("text")] : [],
        tw: Number(head?.getAttribute("data-tw") ?? 0),
        headH: Number(head?.getAttribute("data-h") ?? 0),
      };
      this.spans.set(g, span);
    }
    return span;
  }

  /** Every swimlane of `v`: its name and place (diagram units). */
  spansOf(v: DiagramView): { name: string; x: number; w: number }[] {
    const out: { name: string; x: number; w: number }[] = [];
    for (const g of v.viewport.children) {
      if (!g.classList.contains("lane")) continue;
      const span = this.spanOf(g);
      out.push({ name: g.getAttribute("data-lane") ?? "", x: span.x, w: span.w });
    }
    return out;
  }

  /** A node's box in diagram units, from its data attributes and its lane's (no layout); null for
   * anything else. */
  nodeBox(el: Element): Box | null {
    const lane = el.matches("g.node") ? el.closest("g.lane") : null;
    if (!lane) return null;
    const span = this.spanOf(lane);
    const num = (a: string): number => Number(el.getAttribute(a) ?? 0);
    return { x: span.x + num("data-x"), y: span.y + span.bodyY + num("data-y"), w: num("data-w"), h: num("data-h") };
  }

  /** Swimlanes wholly outside the canvas are not drawn (class `culled`, display: none): at a
   * readable zoom a big diagram shows a few lanes, and the live updates of the others then cost no
   * layout or paint. At most `newLanes` lanes not drawn so far are drawn now (a lane drawn again is
   * laid out anew, all its nodes): the ones nearest the middle; true when some are left for later. */
  cull(v: DiagramView, W: number, newLanes = Infinity): boolean {
    if (!v.view) return false;
    const margin = 200;
    const show: { g: Element; off: number }[] = [];
    for (const g of v.viewport.children) {
      if (!g.classList.contains("lane")) continue;
      const span = this.spanOf(g);
      const left = v.view.x + span.x * v.view.k;
      const right = left + span.w * v.view.k;
      const out = right < -margin || left > W + margin;
      if (out) g.classList.add("culled");
      else if (g.classList.contains("culled")) show.push({ g, off: Math.abs((left + right) / 2 - W / 2) });
    }
    if (show.length > newLanes) show.sort((a, b) => a.off - b.off);
    for (const { g } of show.slice(0, newLanes)) g.classList.remove("culled");
    return show.length > newLanes;
  }

  /** Each lane's header stays on the lane's visible part: at the top of the canvas while the lane
   * goes on below it, its name centred on the part of the lane the canvas shows (a lane wider than
   * the canvas, or partly off it, still says its name). */
  stickHeads(v: DiagramView, W: number): void {
    if (!v.view) return;
    const view: View = v.view;
    for (const g of v.viewport.children) {
      if (!g.classList.contains("lane") || g.classList.contains("culled")) continue;
      const span = this.spanOf(g);
      const head = span.head;
      if (!head) continue;
      const laneH = Number(span.bg?.getAttribute("height") ?? 0);
      const place = laneHeadPlace(
        { x: span.x, y: span.y, w: span.w, h: laneH, textW: span.tw, headH: span.headH },
        view,
        W,
      );
      if (!place) continue;
      const at = `${place.cx.toFixed(1)},${place.dy.toFixed(1)}`;
      if (this.headAt.get(head) === at) continue;
      this.headAt.set(head, at);
      if (place.dy > 0) head.setAttribute("transform", `translate(0,${place.dy.toFixed(1)})`);
      else head.removeAttribute("transform");
      for (const t of span.texts) t.setAttribute("x", place.cx.toFixed(1));
    }
  }
}
