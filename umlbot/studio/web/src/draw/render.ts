// SVG drawing of the laid-out diagrams, and the live part: the state's changes are applied as
// attribute/class/text changes on the existing elements (never a redraw), once per frame.

import { Durations, percentiles } from "../model/durations";
import { safetyStop } from "../model/safety";
import type { ComponentState, Level, NodeStats, StudioState } from "../model/state";
import { edgeKey, nextNodes, nodeKey, TRAIL } from "../model/state";
import type { ModelComponent, ModelView } from "../model/types";
import type { ActivityLayout, ComponentLayout, NodeBox, Point } from "./layout";
import { COMP_STATE_LINES, SMALL_PX, shortGuard, textWidth } from "./layout";
import { REGION_KIND, regionMembers } from "./regions";

const SVGNS = "http://www.w3.org/2000/svg";
/** A called component's box is lit this long (ms), at most once every FLASH_EVERY_MS. */
export const FLASH_MS = 200;
export const FLASH_EVERY_MS = 300;

export function svgEl<K extends keyof SVGElementTagNameMap>(
  tag: K,
  attrs: Record<string, string | number> = {},
  parent?: Element,
  text?: string,
): SVGElementTagNameMap[K] {
  const e = document.createElementNS(SVGNS, tag);
  for (const [k, v] of Object.entries(attrs)) e.setAttribute(k, String(v));
  if (text !== undefined) e.textContent = text;
  if (parent) parent.appendChild(e);
  return e;
}

export function fmtMs(v: number): string {
  if (v >= 100) return v.toFixed(0);
  if (v >= 10) return v.toFixed(1);
  if (v >= 1) return v.toFixed(2);
  return v.toFixed(3);
}
const attrNum = (v: number): string => String(Math.round(v * 1000) / 1000);

function json(v: unknown): string {
  try {
    const s = JSON.stringify(v);
    return s === undefined ? "null" : s;
  } catch {
    return String(v);
  }
}
const clip = (s: string, n: number): string => (s.length > n ? `${s.slice(0, n - 1)}…` : s);

interface NodeEl {
  g: SVGGElement;
  stats: SVGTextElement;
  statsLines: [SVGTSpanElement, SVGTSpanElement] | null; // two lines beside small nodes
  value: SVGTextElement | null;
  title: SVGTitleElement;
  label: string;
  count: number;
  level: Level;
  message: string;
  valueText: string;
}
interface EdgeEl {
  g: SVGGElement;
  label: SVGTextElement | null;
  guard: string;
  count: number;
}
interface CompEl {
  g: SVGGElement;
  state: SVGTextElement;
  box: SVGRectElement;
  flashedAt: number;
  implText: Text;
  implTitle: SVGTitleElement;
  model: ModelComponent;
  driver: string;
}

export interface DiagramView {
  id: string;
  svg: SVGSVGElement;
  viewport: SVGGElement;
  width: number;
  height: number;
  view: { x: number; y: number; k: number } | null;
  /** Where a reader starts (the first start node's centre, diagram units); a view opens there. */
  focus?: Point;
}

export interface Mark {
  level: Level;
  message: string;
}

export class Renderer {
  nodeEls = new Map<string, NodeEl>();
  edgeEls = new Map<string, EdgeEl>();
  compEls = new Map<string, CompEl>();
  orchBox: { g: SVGGElement; text: SVGTextElement; title: SVGTitleElement } | null = null;
  renderedTrails = new Map<string, string[]>();
  renderedRunning = new Map<string, string[]>(); // per lane: nodes running now (after the current one)
  marks = new Map<string, Mark>(); // compiler diagnostics on nodes
  virtualLanes = new Set<string>();
  /** a node inside a collapsed region (draw/regions.ts) -> the region's box; the box -> its nodes */
  regionOf = new Map<string, string>();
  private regionNodes = new Map<string, string[]>();
  private freshNodes: string[] = [];
  private freshEdges: string[] = [];
  private freshLanes = new Set<string>();
  private freshComps: string[] = [];
  // Lanes drawn so far, by name: an identical lane (same geometry) is moved into the new drawing
  // as it is after an edit, so an edit redraws only the lanes it changed.
  private built = new Map<string, BuiltLane>();
  private pool = new Map<string, BuiltLane>();

  /** Bring elements built since the last call up to date with `state` (nodes within the budget). */
  adoptFresh(state: StudioState): void {
    for (const key of this.freshNodes) state.dirtyNodes.add(key);
    for (const key of this.freshEdges) {
      const ee = this.edgeEls.get(key);
      if (ee) this.renderEdge(ee, state.edges.get(key) ?? 0);
    }
    for (const lane of this.freshLanes) this.renderTrail(lane, state.trails.get(lane) ?? [], state);
    for (const name of this.freshComps) {
      const ce = this.compEls.get(name);
      if (ce) this.renderComponent(ce, state.components.get(name));
    }
    this.freshNodes = [];
    this.freshEdges = [];
    this.freshLanes.clear();
    this.freshComps = [];
  }

  reset(model: ModelView | null): void {
    // lanes of an unfinished redraw stay reusable
    for (const [name, b] of this.built) this.pool.set(name, b);
    this.built = new Map();
    this.freshNodes = [];
    this.freshEdges = [];
    this.freshLanes.clear();
    this.freshComps = [];
    this.nodeEls.clear();
    this.edgeEls.clear();
    this.compEls.clear();
    this.orchBox = null;
    this.renderedTrails.clear();
    this.renderedRunning.clear();
    this.regionOf.clear();
    this.regionNodes.clear();
    this.virtualLanes = new Set(
      (model?.diagrams ?? []).flatMap((d) => d.lanes.filter((l) => l.virtual).map((l) => l.name)),
    );
  }

  private newSvg(id: string, width: number, height: number): DiagramView {
    const svg = svgEl("svg", { class: "diagram", "data-diagram": id });
    const defs = svgEl("defs", {}, svg);
    const marker = svgEl(
      "marker",
      {
        id: `arrow-${id}`,
        viewBox: "0 0 10 10",
        refX: 9,
        refY: 5,
        markerWidth: 9,
        markerHeight: 9,
        orient: "auto-start-reverse",
        markerUnits: "userSpaceOnUse",
      },
      defs,
    );
    svgEl("path", { d: "M0,0 L10,5 L0,10 z", class: "arrowhead" }, marker);
    const viewport = svgEl("g", { class: "viewport" }, svg);
    return { id, svg, viewport, width, height, view: null };
  }

  /**
   * Draw an activity diagram lane by lane, yielding to the browser between lanes (a big diagram
   * drawn in the background must not block a frame); null when `stale()` turns true meanwhile.
   */
  async buildActivity(layout: ActivityLayout, stale: () => boolean, reuse?: DiagramView): Promise<DiagramView | null> {
    const d = layout.diagram;
    // After an edit the diagram's drawing is updated in place: unchanged lanes stay where they are
    // (moving thousands of elements into a new <svg> would restyle all of them), changed lanes are
    // drawn anew and swapped in.
    const v = reuse ?? this.newSvg(d.id, layout.width, layout.height);
    v.width = layout.width;
    v.height = layout.height;
    v.focus = undefined;
    for (const lg of layout.lanes) {
      const nb = lg.nodes.find((b) => b.node.kind === "start");
      if (nb) {
        v.focus = { x: lg.x + nb.x + nb.w / 2, y: lg.y + lg.headerH + nb.y + nb.h / 2 };
        break;
      }
    }
    const marker = `url(#arrow-${d.id})`;
    let budget = performance.now();
    const mine = new Set<SVGGElement>();
    for (const lg of layout.lanes) {
      if (performance.now() - budget > 12) {
        await new Promise((resolve) => setTimeout(resolve, 0));
        if (stale()) return null;
        budget = performance.now();
      }
      const lane = lg.lane;
      for (const nb of lg.nodes) {
        if (nb.node.kind !== REGION_KIND) continue;
        const rk = nodeKey(lane.name, nb.node.id);
        const members = regionMembers(nb.node).map((id) => nodeKey(lane.name, id));
        this.regionNodes.set(rk, members);
        for (const m of members) this.regionOf.set(m, rk);
      }
      const key = laneKey(lg, this.virtualLanes);
      const old = this.pool.get(lane.name);
      if (old && old.key === key) {
        this.pool.delete(lane.name);
        if (old.g.parentNode !== v.viewport) v.viewport.append(old.g);
        const at = `translate(${lg.x},${lg.y})`;
        if (old.g.getAttribute("transform") !== at) old.g.setAttribute("transform", at);
        const bg = old.g.querySelector(".lane-bg");
        if (bg && bg.getAttribute("height") !== String(lg.h)) bg.setAttribute("height", String(lg.h));
        // (looked at again, not rewritten: its elements still show what they showed, and a
        // rewrite of thousands of nodes after each edit costs a style and layout pass of them all)
        for (const [k, ne] of old.nodes) {
          this.nodeEls.set(k, ne);
          this.freshNodes.push(k);
        }
        for (const [k, ee] of old.edges) {
          this.edgeEls.set(k, ee);
          this.freshEdges.push(k);
        }
        this.freshLanes.add(lane.name);
        this.built.set(lane.name, old);
        mine.add(old.g);
        continue;
      }
      const laneNodes = new Map<string, NodeEl>();
      const laneEdges = new Map<string, EdgeEl>();
      const g = svgEl("g", { class: "lane", "data-lane": lane.name, transform: `translate(${lg.x},${lg.y})` });
      this.built.set(lane.name, { key, g, nodes: laneNodes, edges: laneEdges });
      mine.add(g);
      svgEl("rect", { class: "lane-bg", x: 0, y: 0, width: lg.w, height: lg.h }, g);
      const body = svgEl("g", { class: "lane-body", transform: `translate(0,${lg.headerH})` }, g);
      const edgesG = svgEl("g", { class: "edges" }, body);
      const nodesG = svgEl("g", { class: "nodes" }, body);
      for (const e of lg.edges) {
        const eg = svgEl(
          "g",
          { class: "edge", "data-lane": lane.name, "data-source": e.source, "data-target": e.target, "data-count": 0 },
          edgesG,
        );
        const d = roundedPath(e.points);
        svgEl("path", { class: "line", d, "marker-end": marker }, eg);
        svgEl("path", { class: "hit", d }, eg); // a wide invisible stroke to click an edge (edit mode)
        let label: SVGTextElement | null = null;
        if (e.labelBox) {
          // centred on its flow (an inline ELK label: the flow runs through the label's box)
          const text = shortGuard(e.label);
          label = svgEl(
            "text",
            { class: "elabel guard", x: e.labelBox.x + e.labelBox.w / 2, y: e.labelBox.y + 12 },
            eg,
            text,
          );
          if (text !== e.label) svgEl("title", {}, eg, e.label);
        }
        const ek = edgeKey(lane.name, e.source, e.target);
        const ee = { g: eg, label, guard: shortGuard(e.label), count: -1 };
        this.edgeEls.set(ek, ee);
        laneEdges.set(ek, ee);
        this.freshEdges.push(ek);
      }
      for (const nb of lg.nodes) {
        const k = this.buildNode(nodesG, lane.name, nb);
        laneNodes.set(k, this.nodeEls.get(k)!);
      }
      // The header, after the body: the page keeps it on the lane's visible part (core/lanes.ts,
      // stickHeads), over the nodes it passes. `data-tw`: its widest text's width.
      // focusable (keyboard: features/keyboard): Tab reaches a lane's nodes, then its header
      const head = svgEl(
        "g",
        {
          class: "lane-head",
          "data-h": lg.headerH,
          tabindex: 0,
          role: "button", // named by its texts
        },
        g,
      );
      svgEl("rect", { class: "lane-header", x: 0, y: 0, width: lg.w, height: lg.headerH }, head);
      // a virtual lane is a called activity; a component's lane runs on that component: the
      // stereotype on its own line above the name (UML's way; side by side they overlapped)
      const sub = lane.virtual ? "«activity»" : lane.component ? "«component»" : "";
      if (sub) svgEl("text", { class: "lane-sub", x: lg.w / 2, y: 15 }, head, sub);
      svgEl("text", { class: "lane-title", x: lg.w / 2, y: sub ? 34 : 28 }, head, lane.name);
      head.setAttribute(
        "data-tw",
        String(Math.max(textWidth(lane.name, 15, "600"), sub ? textWidth(sub, SMALL_PX) : 0)),
      );
      this.freshLanes.add(lane.name);
      // swap it in whole (its old drawing, if any, goes below)
      const was = old && old.g.parentNode === v.viewport ? old.g : null;
      if (was) {
        was.replaceWith(g);
        this.pool.delete(lane.name);
      } else v.viewport.append(g);
    }
    for (const g of [...v.viewport.children])
      if (g.classList.contains("lane") && !mine.has(g as SVGGElement)) g.remove();
    for (const [name, b] of this.pool) if (!b.g.isConnected) this.pool.delete(name);
    return v;
  }

  private buildNode(parent: SVGGElement, lane: string, nb: NodeBox): string {
    const n = nb.node;
    const { w, h } = nb;
    // Absolute coordinates, no transform per node: thousands of transform nodes make Chromium's
    // paint and layerization slow.
    const X = (v: number): number => nb.x + v;
    const Y = (v: number): number => nb.y + v;
    const pts = (list: [number, number][]): string => list.map(([a, b]) => `${X(a)},${Y(b)}`).join(" ");
    const g = svgEl(
      "g",
      {
        class: `node kind-${n.kind}`,
        "data-lane": lane,
        "data-node": n.id,
        "data-kind": n.kind,
        "data-count": 0,
        "data-x": attrNum(nb.x),
        "data-y": attrNum(nb.y),
        "data-w": nb.w,
        "data-h": nb.h,
        tabindex: 0,
        role: "button",
      },
      parent,
    );
    const title = svgEl("title", {}, g, n.label);
    let labelY = 21;
    switch (n.kind) {
      case "start":
        svgEl("circle", { class: "shape", cx: X(w / 2), cy: Y(h / 2), r: w / 2 }, g);
        break;
      case "end":
        svgEl("circle", { class: "shape", cx: X(w / 2), cy: Y(h / 2), r: w / 2 }, g);
        svgEl("circle", { class: "dot", cx: X(w / 2), cy: Y(h / 2), r: w / 2 - 5 }, g);
        break;
      case "fork":
      case "join":
        svgEl("rect", { class: "shape bar", x: X(0), y: Y(0), width: w, height: h, rx: 2 }, g);
        break;
      case "decision":
        svgEl(
          "polygon",
          {
            class: "shape",
            points: pts([
              [w / 2, 0],
              [w, h / 2],
              [w / 2, h],
              [0, h / 2],
            ]),
          },
          g,
        );
        labelY = h / 2 + 4.5;
        break;
      case "datastore":
        svgEl("rect", { class: "shape", x: X(0), y: Y(0), width: w, height: h, rx: 2 }, g);
        svgEl("text", { class: "stereo", x: X(w / 2), y: Y(13) }, g, "«datastore»");
        labelY = 30;
        break;
      case "send":
        svgEl(
          "polygon",
          {
            class: "shape",
            points: pts([
              [0, 0],
              [w - 18, 0],
              [w, h / 2],
              [w - 18, h],
              [0, h],
            ]),
          },
          g,
        );
        break;
      case REGION_KIND:
        // a collapsed region: a box with a double edge and a ⊞ (open by click, Enter or Space)
        svgEl("rect", { class: "shape region-back", x: X(4), y: Y(4), width: w, height: h, rx: 6 }, g);
        svgEl("rect", { class: "shape", x: X(0), y: Y(0), width: w, height: h, rx: 6 }, g);
        svgEl("text", { class: "region-mark", x: X(14), y: Y(21) }, g, "⊞");
        g.setAttribute("aria-expanded", "false");
        g.setAttribute("aria-label", `${n.label} (collapsed: Enter opens it)`);
        title.textContent = `${n.label} Click, Enter or Space to open it.`;
        break;
      case "accept":
        svgEl(
          "polygon",
          {
            class: "shape",
            points: pts([
              [0, 0],
              [w, 0],
              [w, h],
              [0, h],
              [18, h / 2],
            ]),
          },
          g,
        );
        break;
      default:
        svgEl("rect", { class: "shape", x: X(0), y: Y(0), width: w, height: h, rx: 11 }, g);
    }
    if (n.kind !== "start" && n.kind !== "end" && n.kind !== "fork" && n.kind !== "join") {
      const lx =
        n.kind === "send"
          ? (w - 18) / 2
          : n.kind === "accept"
            ? (w + 18) / 2
            : n.kind === REGION_KIND
              ? w / 2 + 8
              : w / 2;
      svgEl("text", { class: "label", x: X(lx), y: Y(labelY) }, g, n.label);
    }
    const called = n.kind === "action" ? n.label.replace(/\(\s*\)$/, "") : "";
    if (called && this.virtualLanes.has(called)) {
      // UML call behaviour action: the rake symbol.
      g.classList.add("calls");
      g.setAttribute("data-calls", called);
      // (14 x 14 units: big enough to see and to click at the zoom a diagram opens at)
      svgEl("path", { class: "rake", d: `M${X(w - 17)},${Y(h - 5)} v-14 M${X(w - 24)},${Y(h - 5)} v-7 h14 v7` }, g);
    }
    if (n.kind !== "end" && n.kind !== REGION_KIND) {
      // the output port (edit mode shows it): drag from it to another node to connect them
      svgEl("circle", { class: "port-out", cx: X(w / 2), cy: Y(h), r: 6 }, g);
    }
    let value: SVGTextElement | null = null;
    if (n.kind === "datastore") value = svgEl("text", { class: "value", x: X(w / 2), y: Y(47) }, g, "—");
    let stats: SVGTextElement;
    let statsLines: [SVGTSpanElement, SVGTSpanElement] | null = null;
    if (nb.statsInside) {
      stats = svgEl("text", { class: "stats", x: nb.statsX, y: nb.statsY }, g, "×0");
    } else {
      stats = svgEl("text", { class: "stats outside", x: nb.statsX, y: nb.statsY }, g);
      statsLines = [svgEl("tspan", { x: nb.statsX }, stats, "×0"), svgEl("tspan", { x: nb.statsX, dy: 13 }, stats, "")];
    }
    const key = nodeKey(lane, n.id);
    this.nodeEls.set(key, {
      g,
      stats,
      statsLines,
      value,
      title,
      label: n.label,
      count: -2,
      level: "info",
      message: "",
      valueText: "",
    });
    this.freshNodes.push(key);
    return key;
  }

  buildComponents(layout: ComponentLayout, model: ModelView): DiagramView {
    const v = this.newSvg("components", layout.width, layout.height);
    const marker = "url(#arrow-components)";
    const linksG = svgEl("g", { class: "links" }, v.viewport);
    for (const l of layout.links) {
      const g = svgEl("g", { class: "link", "data-link": l.id }, linksG);
      svgEl("path", { class: "line", d: roundedPath(l.points), "marker-end": marker }, g);
      svgEl("text", { class: "elabel", x: l.labelX, y: l.labelY }, g, l.label);
    }
    const o = layout.orch;
    const og = svgEl(
      "g",
      { class: "orchestrator", "data-state": "unknown", transform: `translate(${o.x},${o.y})` },
      v.viewport,
    );
    const otitle = svgEl("title", {}, og, "unknown");
    svgEl("rect", { class: "box", width: o.w, height: o.h, rx: 4 }, og);
    svgEl("text", { class: "stereo", x: 12, y: 18 }, og, "«orchestrator»");
    svgEl("text", { class: "name", x: 12, y: 38 }, og, model.name);
    const otext = svgEl("text", { class: "orch-state", x: 12, y: 58 }, og, "unknown");
    svgEl("circle", { class: "dot", cx: o.w - 16, cy: 16, r: 6 }, og);
    this.orchBox = { g: og, text: otext, title: otitle };

    for (const c of layout.components) {
      const m = model.components.find((mc) => mc.name === c.name);
      if (!m) continue;
      const g = svgEl(
        "g",
        {
          class: "component unknown",
          "data-component": c.name,
          "data-state": "unknown",
          "data-x": attrNum(c.x),
          "data-y": attrNum(c.y),
          tabindex: 0,
          role: "button", // (named by its texts)
        },
        v.viewport,
      );
      const inner = svgEl("g", { transform: `translate(${c.x},${c.y})` }, g);
      const box = svgEl("rect", { class: "box", width: c.w, height: c.h, rx: 3 }, inner);
      // UML component icon
      svgEl(
        "path",
        { class: "icon", d: `M${c.w - 26},8 h14 v16 h-14 z M${c.w - 30},11 h8 v3 h-8 z M${c.w - 30},18 h8 v3 h-8 z` },
        inner,
      );
      svgEl("text", { class: "stereo", x: 12, y: 18 }, inner, `«${m.kind}»`);
      svgEl("text", { class: "name", x: 12, y: 37 }, inner, c.name);
      svgEl("circle", { class: "dot", cx: c.w - 42, cy: 16, r: 6 }, inner);
      const implLine = svgEl("g", { class: "impl-line" }, inner); // (its tooltip is not in the text)
      const implTitle = svgEl("title", {}, implLine);
      const implText = svgEl("text", { class: "impl", x: 12, y: 54 }, implLine).appendChild(
        document.createTextNode(""),
      );
      svgEl("text", { class: "features", x: 12, y: 69 }, inner, `features: ${m.features.join(", ")}`);
      svgEl("line", { class: "sep", x1: 0, x2: c.w, y1: 77, y2: 77 }, inner);
      const state = svgEl("text", { class: "state", x: 12, y: 92 }, inner);
      for (const p of c.ports) {
        svgEl("rect", { class: "port", x: p.x - c.x, y: p.y - c.y, width: p.w, height: p.h }, inner);
        svgEl("text", { class: "port-label", x: p.labelX - c.x, y: p.labelY - c.y }, inner, `${p.name} → ${p.feature}`);
      }
      this.compEls.set(c.name, { g, state, box, flashedAt: -1e9, implText, implTitle, model: m, driver: "?" });
      this.freshComps.push(c.name);
    }
    return v;
  }

  /**
   * Apply what changed in `state` to the elements (once per animation frame). Node updates stop
   * after `budgetMs` (the rest stays dirty for the next frame); 0 = no limit.
   */
  flush(state: StudioState, budgetMs = 0): void {
    const all = state.allDirty;
    const dirty = state.dirtyNodes;
    if (all) {
      for (const [key, ne] of this.nodeEls) {
        ne.count = -2; // forces a full rewrite of this node
        dirty.add(key);
      }
      for (const [key, ee] of this.edgeEls) this.renderEdge(ee, state.edges.get(key) ?? 0);
      const lanes = new Set([...this.renderedTrails.keys(), ...this.renderedRunning.keys(), ...state.trails.keys()]);
      for (const lane of lanes) this.renderTrail(lane, state.trails.get(lane) ?? [], state);
      for (const [name, ce] of this.compEls) this.renderComponent(ce, state.components.get(name));
    } else {
      for (const key of state.dirtyEdges) {
        const ee = this.edgeEls.get(key);
        if (ee) this.renderEdge(ee, state.edges.get(key) ?? 0);
      }
      for (const lane of state.dirtyLanes) this.renderTrail(lane, state.trails.get(lane) ?? [], state);
      for (const name of state.dirtyComponents) {
        const ce = this.compEls.get(name);
        if (ce) this.renderComponent(ce, state.components.get(name));
      }
    }
    // A component that was just called flashes (at most every FLASH_EVERY_MS): its box is lit for
    // FLASH_MS, one repaint on and one off. Not an animation: a fading fill repainted the diagram
    // in every frame while the robot kept calling (the page's main thread busy painting; it did
    // not explain the live highlight's ~30 ms before a message is taken: docs/performance.md).
    const now = performance.now();
    for (const name of state.calledComponents) {
      const ce = this.compEls.get(name);
      if (!ce || now - ce.flashedAt < FLASH_EVERY_MS || ce.g.getAttribute("data-state") === "offline") continue;
      ce.flashedAt = now;
      const box = ce.box;
      box.classList.add("flash");
      setTimeout(() => box.classList.remove("flash"), FLASH_MS);
    }
    const t0 = performance.now();
    let n = 0;
    for (const key of dirty) {
      dirty.delete(key);
      const rk = this.regionOf.get(key) ?? (this.regionNodes.has(key) ? key : null);
      const ne = this.nodeEls.get(rk ?? key);
      if (ne && rk) {
        this.renderNode(ne, this.regionStats(state, rk), rk, ne.count === -2);
        // a region's box says how often the run went in; the times are its nodes' own
        ne.stats.textContent = `×${ne.count} in`;
        for (const a of ["data-last-ms", "data-p50-ms", "data-p99-ms"]) ne.g.removeAttribute(a);
      } else if (ne) this.renderNode(ne, state.nodes.get(key), key, ne.count === -2);
      if (budgetMs > 0 && (++n & 31) === 0 && performance.now() - t0 > budgetMs) break;
    }
    if ((all || state.dirtyOrch) && this.orchBox) {
      this.orchBox.g.setAttribute("data-state", state.orch.state);
      const text = state.orch.state + (state.orch.detail ? ` — ${state.orch.detail}` : "");
      this.orchBox.text.textContent = clip(text, 62);
      this.orchBox.title.textContent = text;
    }
  }

  private renderNode(ne: NodeEl, s: NodeStats | undefined, key: string, force: boolean): void {
    const count = s ? s.count : 0;
    const mark = this.marks.get(key);
    let level: Level = s ? s.level : "info";
    let message = s ? s.message : "";
    if (mark && (level === "info" || (level === "warning" && mark.level === "error"))) {
      level = mark.level;
      message = mark.message;
    }
    if (count !== ne.count || force) {
      ne.count = count;
      const g = ne.g;
      g.setAttribute("data-count", String(count));
      if (s && count > 0) {
        const [p50, p99] = percentiles(s.durs);
        g.setAttribute("data-last-ms", attrNum(s.lastMs));
        g.setAttribute("data-p50-ms", attrNum(p50));
        g.setAttribute("data-p99-ms", attrNum(p99));
        const head = `×${count} · ${fmtMs(s.lastMs)} ms · `;
        const tail = `p50 ${fmtMs(p50)} · p99 ${fmtMs(p99)}`;
        if (ne.statsLines) {
          ne.statsLines[0].textContent = head;
          ne.statsLines[1].textContent = tail;
        } else ne.stats.textContent = head + tail;
      } else {
        g.removeAttribute("data-last-ms");
        g.removeAttribute("data-p50-ms");
        g.removeAttribute("data-p99-ms");
        if (ne.statsLines) {
          ne.statsLines[0].textContent = "×0";
          ne.statsLines[1].textContent = "";
        } else ne.stats.textContent = "×0";
      }
      g.classList.toggle("ran", count > 0);
      if (ne.value) {
        const text = s?.hasValue ? json(s.value) : "";
        if (text !== ne.valueText || force) {
          ne.valueText = text;
          if (text) ne.g.setAttribute("data-value", text);
          else ne.g.removeAttribute("data-value");
          ne.value.textContent = text ? clip(text, 48) : "—";
        }
      }
    }
    if (level !== ne.level || message !== ne.message || force) {
      ne.level = level;
      ne.message = message;
      ne.g.classList.toggle("error", level === "error");
      ne.g.classList.toggle("warning", level === "warning");
      if (level !== "info") {
        ne.g.setAttribute("data-message", message);
        ne.title.textContent = message;
      } else {
        ne.g.removeAttribute("data-message");
        ne.title.textContent = ne.label;
      }
    }
  }

  /** A node's element, or the collapsed region's box that holds it. */
  nodeEl(key: string): NodeEl | undefined {
    return this.nodeEls.get(key) ?? this.nodeEls.get(this.regionOf.get(key) ?? "");
  }

  /** A collapsed region's figures: how often the run went in (its first node's count), and the
   * worst problem of a node inside. */
  private regionStats(state: StudioState, rk: string): NodeStats | undefined {
    const members = this.regionNodes.get(rk) ?? [];
    const entry = state.nodes.get(members[0] ?? "");
    let level: Level = "info";
    let message = "";
    for (const m of members) {
      const s = state.nodes.get(m);
      const mark = this.marks.get(m);
      for (const c of [s, mark]) {
        if (!c || c.level === "info" || (level === "error" && c.level !== "error") || c.level === level) continue;
        level = c.level;
        message = c.message;
      }
    }
    if (!entry && level === "info") return undefined;
    return {
      count: entry?.count ?? 0,
      lastMs: entry?.lastMs ?? 0,
      durs: entry?.durs ?? new Durations(),
      hasValue: false,
      value: undefined,
      level,
      message,
      lastIdx: entry?.lastIdx ?? 0,
    };
  }

  private renderEdge(ee: EdgeEl, count: number): void {
    if (ee.count === count) return;
    ee.count = count;
    ee.g.setAttribute("data-count", String(count));
    ee.g.classList.toggle("taken", count > 0);
    if (ee.label) ee.label.textContent = count > 0 ? `${ee.guard}  ×${count}` : ee.guard;
  }

  private renderTrail(lane: string, trail: string[], state: StudioState): void {
    for (const id of this.renderedRunning.get(lane) ?? [])
      this.nodeEl(nodeKey(lane, id))?.g.classList.remove("running");
    const running = trail.length
      ? nextNodes(state.index, lane, trail[0], state.nodes.get(nodeKey(lane, trail[0])))
      : [];
    for (const id of running) this.nodeEl(nodeKey(lane, id))?.g.classList.add("running");
    this.renderedRunning.set(lane, running);
    const old = this.renderedTrails.get(lane) ?? [];
    for (const id of old) {
      const ne = this.nodeEl(nodeKey(lane, id));
      if (ne) {
        ne.g.classList.remove("active", "trail");
        ne.g.removeAttribute("data-trail");
      }
    }
    trail.slice(0, TRAIL).forEach((id, i) => {
      const ne = this.nodeEl(nodeKey(lane, id));
      if (!ne) return;
      if (i === 0) ne.g.classList.add("active");
      else if (!ne.g.classList.contains("active")) {
        ne.g.classList.add("trail");
        ne.g.setAttribute("data-trail", String(i));
      }
    });
    this.renderedTrails.set(lane, trail.slice(0, TRAIL));
  }

  private renderComponent(ce: CompEl, cs: ComponentState | undefined): void {
    const avail = cs ? cs.avail : "unknown";
    const g = ce.g;
    g.setAttribute("data-state", avail);
    g.classList.toggle("online", avail === "online");
    g.classList.toggle("offline", avail === "offline");
    g.classList.toggle("unknown", avail === "unknown");
    const driver = cs?.driver ?? "";
    if (driver !== ce.driver) {
      // the driver the service runs (its status says it, `auto` resolved), else the deployment's
      ce.driver = driver;
      const m = ce.model;
      const shown = driver && driver !== m.driver ? `${m.driver} → ${driver}` : m.driver;
      ce.implText.data = `${m.impl} · ${m.service} · ${shown}`;
      if (driver) g.setAttribute("data-driver", driver);
      else g.removeAttribute("data-driver");
      ce.implTitle.textContent = driver
        ? `implementation ${m.impl}, ${m.service} service, running driver ${driver} (the deployment says ${m.driver})`
        : `implementation ${m.impl}, ${m.service} service, driver ${m.driver} (as the deployment says; the service has not said which it runs)`;
    }
    while (ce.state.firstChild) ce.state.firstChild.remove();
    // a safety stop its service made (a motor's `stop_reason`: watchdog, …) is marked on the
    // component until the motor runs again: why the car stood still, after the run too
    const stop = safetyStop(cs?.retained);
    g.classList.toggle("safety-stop", stop !== null);
    if (stop !== null) g.setAttribute("data-stop-reason", stop);
    else g.removeAttribute("data-stop-reason");
    if (cs?.hasRetained) {
      g.setAttribute("data-retained", json(cs.retained));
      const r = cs.retained;
      let lines: string[];
      if (r && typeof r === "object" && !Array.isArray(r)) {
        lines = Object.entries(r as Record<string, unknown>)
          .filter(([k]) => !(stop !== null && k === "stop_reason"))
          .map(([k, v]) => `${k}: ${json(v)}`);
        if (stop !== null) lines.unshift(`⚠ safety stop: ${stop}`); // first, where it is seen
      } else lines = [json(r)];
      if (lines.length > COMP_STATE_LINES) {
        lines = lines.slice(0, COMP_STATE_LINES - 1).concat([`… ${lines.length - COMP_STATE_LINES + 1} more`]);
      }
      lines.forEach((line, i) => {
        const attrs: Record<string, string | number> = { x: 12, dy: i === 0 ? 0 : 15 };
        if (i === 0 && stop !== null) attrs.class = "stop";
        svgEl("tspan", attrs, ce.state, clip(line, 40) + (i < lines.length - 1 ? " " : ""));
      });
    } else {
      g.removeAttribute("data-retained");
      ce.state.textContent = "no retained state";
    }
  }
}

interface BuiltLane {
  key: string;
  g: SVGGElement;
  nodes: Map<string, NodeEl>;
  edges: Map<string, EdgeEl>;
}

/** What a lane's drawing depends on (not the nodes' source lines, which shift with edits elsewhere). */
function laneKey(lg: ActivityLayout["lanes"][number], virtualLanes: Set<string>): string {
  const l = lg.lane;
  return JSON.stringify([
    lg.y,
    lg.w,
    l.name,
    l.file,
    l.virtual,
    l.component, // x and the column height are updated in place
    lg.nodes.map((nb) => [
      nb.node.id,
      nb.node.kind,
      nb.node.label,
      nb.x,
      nb.y,
      nb.w,
      nb.h,
      nb.statsX,
      nb.statsY,
      nb.node.kind === "action" && virtualLanes.has(nb.node.label.replace(/\(\s*\)$/, "")),
    ]),
    lg.edges.map((e) => [e.source, e.target, e.label, e.points, e.labelBox]),
  ]);
}

function roundedPath(pts: Point[]): string {
  if (pts.length === 0) return "";
  const r = 6;
  let d = `M${pts[0].x},${pts[0].y}`;
  for (let i = 1; i < pts.length - 1; i++) {
    const p = pts[i];
    const a = pts[i - 1];
    const b = pts[i + 1];
    const la = Math.hypot(p.x - a.x, p.y - a.y);
    const lb = Math.hypot(b.x - p.x, b.y - p.y);
    const rr = Math.min(r, la / 2, lb / 2);
    if (rr < 0.5) {
      d += ` L${p.x},${p.y}`;
      continue;
    }
    const p1 = { x: p.x + ((a.x - p.x) * rr) / la, y: p.y + ((a.y - p.y) * rr) / la };
    const p2 = { x: p.x + ((b.x - p.x) * rr) / lb, y: p.y + ((b.y - p.y) * rr) / lb };
    d += ` L${p1.x},${p1.y} Q${p.x},${p.y} ${p2.x},${p2.y}`;
  }
  const last = pts[pts.length - 1];
  d += ` L${last.x},${last.y}`;
  return d;
}
