// Automatic layout with ELK (elkjs, run in its Web Worker). Activity diagrams: each lane is laid
// out on its own (layered, direction DOWN) and the lanes are placed side by side as columns with a
// header each; edges stay inside their lane. The component diagram is one layered graph (RIGHT)
// with the link ports on the component boxes.

import type { ElkExtendedEdge, ElkNode } from "elkjs/lib/elk-api.js";
import ELK from "elkjs/lib/elk-api.js";
import type { ModelDiagram, ModelLane, ModelNode, ModelView } from "../model/types";
import { keepLayout, keptPart, layoutKey, layoutStats, storedLayout } from "./layout-store";
import { REGION_KIND } from "./regions";
import { type Dir, grow, middle, pathCrosses, type Rect, route } from "./route";

export const FONT = "system-ui, -apple-system, 'Segoe UI', Roboto, 'DejaVu Sans', sans-serif";
export const LABEL_PX = 13;
export const SMALL_PX = 11;
export const STATS_SAMPLE = "×8888 · 888.8 ms · p50 888.8 · p99 888.8";

let elk: InstanceType<typeof ELK> | null = null;
function engine(): InstanceType<typeof ELK> {
  if (!elk) {
    const workerUrl = new URL("./elk-worker.min.js", import.meta.url).href;
    elk = new ELK({ workerUrl });
  }
  return elk;
}

const canvas = document.createElement("canvas");
const ctx = canvas.getContext("2d") as CanvasRenderingContext2D;
/** Start the layout worker early (it has 1.5 MB of script to parse). */
export function warmUp(): void {
  void engine()
    .knownLayoutAlgorithms()
    .catch(() => undefined);
}

export function textWidth(text: string, px: number, weight = "normal"): number {
  ctx.font = `${weight} ${px}px ${FONT}`;
  return Math.ceil(ctx.measureText(text).width);
}

export interface Point {
  x: number;
  y: number;
}
export interface NodeBox {
  node: ModelNode;
  x: number;
  y: number;
  w: number;
  h: number;
  statsX: number;
  statsY: number;
  statsInside: boolean;
}
export interface EdgeGeom {
  id: string;
  source: string;
  target: string;
  label: string;
  points: Point[];
  labelBox: { x: number; y: number; w: number; h: number } | null;
}
export interface LaneGeom {
  lane: ModelLane;
  x: number;
  y: number;
  w: number;
  h: number; // lane column incl. header
  headerH: number;
  nodes: NodeBox[];
  edges: EdgeGeom[];
}
export interface ActivityLayout {
  kind: "activity";
  diagram: ModelDiagram;
  width: number;
  height: number;
  lanes: LaneGeom[];
}

// The header holds the lane's name, with the stereotype («component», «activity») on a line above it.
export const HEADER_H = 44;
/** A guard longer than this is shown cut with an ellipsis (its full text is the label's tooltip). */
export const GUARD_CHARS = 32;
export function shortGuard(text: string): string {
  return text.length > GUARD_CHARS ? `${text.slice(0, GUARD_CHARS - 1)}…` : text;
}
const LANE_GAP = 0;
const STATS_W = () => textWidth(STATS_SAMPLE, SMALL_PX);
// Stats beside a small node (start, end, fork, join, decision) take two lines.
export const STATS2_SAMPLE = "p50 888.8 · p99 888.8";
const STATS2_W = () => textWidth(STATS2_SAMPLE, SMALL_PX) + 4;

/** Room on the right of an action that may call a virtual lane, for its ⋔ mark (the stats are
 * centred left of it, so the mark never covers "p99 …"). */
export const RAKE_W = 26;
/** Whether an action's text is a bare name (`Stop`, `Stop()`): how a virtual lane is called. */
export function mayCallLane(n: ModelNode): boolean {
  return n.kind === "action" && /^[A-Za-z_]\w*(\(\s*\))?$/.test(n.label);
}

export function nodeSize(n: ModelNode): { w: number; h: number; statsInside: boolean } {
  const lw = textWidth(n.label, LABEL_PX);
  const sw = STATS_W();
  switch (n.kind) {
    case "start":
      return { w: 22, h: 22, statsInside: false };
    case "end":
      return { w: 26, h: 26, statsInside: false };
    case "fork":
    case "join":
      return { w: 110, h: 8, statsInside: false };
    case "decision":
      return { w: Math.max(64, lw + 44), h: 44, statsInside: false };
    case "datastore":
      return { w: Math.max(lw + 28, sw + 20, 150), h: 72, statsInside: true };
    case "send":
    case "accept":
      return { w: Math.max(lw + 56, sw + 36), h: 50, statsInside: true };
    case "region": // a collapsed region (draw/regions.ts): its ⊞ left of the text
      return { w: Math.max(lw + 48, sw + 20), h: 50, statsInside: true };
    default:
      return { w: Math.max(lw + 28, sw + 20) + (mayCallLane(n) ? RAKE_W : 0), h: 50, statsInside: true };
  }
}

const LANE_OPTIONS: Record<string, string> = {
  "elk.algorithm": "layered",
  "elk.direction": "DOWN",
  "elk.edgeRouting": "ORTHOGONAL",
  "elk.spacing.nodeNode": "36",
  "elk.layered.spacing.nodeNodeBetweenLayers": "30",
  "elk.layered.spacing.edgeNodeBetweenLayers": "14",
  "elk.spacing.edgeNode": "18",
  "elk.spacing.edgeEdge": "12",
  "elk.spacing.edgeLabel": "3",
  // A guard is an inline label on its own flow, in the first layer after the decision (not in the
  // middle of a long flow, where it floated between parallel flows): a reader sees which branch
  // it names, and ELK reserves its room.
  // (inline and CENTER are set on each label: ELK reads them from the label)
  "elk.layered.edgeLabels.centerLabelPlacementStrategy": "TAIL_LAYER",
  "elk.layered.considerModelOrder.strategy": "NODES_AND_EDGES",
  "elk.layered.cycleBreaking.strategy": "MODEL_ORDER",
  "elk.layered.nodePlacement.strategy": "NETWORK_SIMPLEX",
  "elk.padding": "[top=18,left=24,bottom=24,right=24]",
  "elk.json.edgeCoords": "ROOT",
  "elk.json.shapeCoords": "ROOT",
};

// A lane laid out again after an edit: ELK's interactive strategies take the layers, the order
// within them and the places across from where the nodes were drawn before (the hints), so an
// edit moves the nodes it touches, not the whole lane.
const INTERACTIVE_OPTIONS: Record<string, string> = {
  ...LANE_OPTIONS,
  "elk.layered.cycleBreaking.strategy": "INTERACTIVE",
  "elk.layered.layering.strategy": "INTERACTIVE",
  "elk.layered.crossingMinimization.strategy": "INTERACTIVE",
  "elk.layered.interactiveReferencePoint": "TOP_LEFT",
  // one graph: ELK would lay out a node not yet connected on its own and pack it in beside the
  // rest, at the top
  "elk.separateConnectedComponents": "false",
};

/**
 * The lane's nodes in flow order: a depth-first walk from the start node(s) finds the flows that go
 * back (loops); without them the nodes are sorted topologically (ties in the walk's order). ELK's
 * model-order cycle breaking then turns around exactly the loops' flows, so everything else flows
 * down — whatever order the nodes were written (or added in the page) in: start -> a -> b -> end
 * reads top to bottom even when `end` was written second.
 */
export function flowOrder(lane: ModelLane): ModelNode[] {
  const ids = new Map(lane.nodes.map((n, i) => [n.id, i]));
  const out: number[][] = lane.nodes.map(() => []);
  for (const e of lane.edges) {
    const a = ids.get(e.source);
    const b = ids.get(e.target);
    if (a !== undefined && b !== undefined) out[a].push(b);
  }
  const seen = new Uint8Array(lane.nodes.length); // 0 new, 1 on the stack, 2 done
  const pre = new Array<number>(lane.nodes.length).fill(-1);
  const back = new Set<string>();
  let counter = 0;
  const roots = [
    ...lane.nodes.map((n, i) => (n.kind === "start" ? i : -1)).filter((i) => i >= 0),
    ...lane.nodes.map((_, i) => i),
  ];
  for (const root of roots) {
    if (seen[root]) continue;
    const stack: [number, number][] = [[root, 0]];
    seen[root] = 1;
    pre[root] = counter++;
    while (stack.length) {
      const top = stack[stack.length - 1];
      const [v, k] = top;
      if (k >= out[v].length) {
        seen[v] = 2;
        stack.pop();
        continue;
      }
      top[1] = k + 1;
      const w = out[v][k];
      if (seen[w] === 1) back.add(`${v}>${w}`);
      else if (seen[w] === 0) {
        seen[w] = 1;
        pre[w] = counter++;
        stack.push([w, 0]);
      }
    }
  }
  const indeg = new Array<number>(lane.nodes.length).fill(0);
  for (let v = 0; v < out.length; v++) for (const w of out[v]) if (!back.has(`${v}>${w}`)) indeg[w] += 1;
  // Kahn's algorithm, the ready node first in the walk's order (a small list: lanes are small)
  const ready = lane.nodes.map((_, i) => i).filter((i) => indeg[i] === 0);
  const order: ModelNode[] = [];
  while (ready.length) {
    let best = 0;
    for (let i = 1; i < ready.length; i++) if (pre[ready[i]] < pre[ready[best]]) best = i;
    const v = ready.splice(best, 1)[0];
    order.push(lane.nodes[v]);
    for (const w of out[v]) {
      if (back.has(`${v}>${w}`)) continue;
      if (--indeg[w] === 0) ready.push(w);
    }
  }
  return order.length === lane.nodes.length ? order : lane.nodes;
}

/** Where each node of a lane was drawn before an edit (ELK's top-left corners, lane coordinates). */
type Hints = Map<string, Point>;

async function layoutLane(lane: ModelLane, hints?: Hints): Promise<LaneGeom> {
  const sizes = new Map<string, ReturnType<typeof nodeSize>>();
  const children: ElkNode[] = flowOrder(lane).map((n) => {
    const s = nodeSize(n);
    sizes.set(n.id, s);
    const child: ElkNode = { id: n.id, width: s.w, height: s.h };
    const at = hints?.get(n.id);
    if (at) {
      child.x = at.x;
      child.y = at.y;
    }
    if (!s.statsInside) {
      child.labels = [{ id: `${n.id}#stats`, text: "stats", width: STATS2_W(), height: 28 }];
      child.layoutOptions = { "elk.nodeLabels.placement": "OUTSIDE V_CENTER H_RIGHT" };
    }
    return child;
  });
  const known = new Set(lane.nodes.map((n) => n.id));
  const edges: ElkExtendedEdge[] = lane.edges
    .filter((e) => known.has(e.source) && known.has(e.target))
    .map((e) => {
      const edge: ElkExtendedEdge = { id: e.id, sources: [e.source], targets: [e.target] };
      if (e.label) {
        const text = shortGuard(e.label);
        edge.labels = [
          {
            id: `${e.id}#label`,
            text,
            width: guardWidth(e.label),
            height: 16,
            layoutOptions: { "elk.edgeLabels.inline": "true", "elk.edgeLabels.placement": "CENTER" },
          },
        ];
      }
      return edge;
    });
  const graph: ElkNode = { id: "root", layoutOptions: hints ? INTERACTIVE_OPTIONS : LANE_OPTIONS, children, edges };
  const out = await laidOut(graph, !hints);
  const nodes: NodeBox[] = [];
  const byId = new Map(lane.nodes.map((n) => [n.id, n]));
  for (const c of out.children ?? []) {
    const n = byId.get(c.id);
    if (!n) continue;
    const s = sizes.get(c.id)!;
    const x = c.x ?? 0;
    const y = c.y ?? 0;
    let statsX = x + (s.w - (mayCallLane(n) ? RAKE_W : 0)) / 2;
    let statsY = y + s.h - 9;
    if (!s.statsInside) {
      // ELK reserved room for the stats on the right (an outside node label); place them there.
      statsX = x + s.w + 8;
      statsY = y + s.h / 2 - 3;
    }
    nodes.push({ node: n, x, y, w: s.w, h: s.h, statsX, statsY, statsInside: s.statsInside });
  }
  const byEdge = new Map(lane.edges.map((e) => [e.id, e]));
  const edgeGeoms: EdgeGeom[] = [];
  for (const e of out.edges ?? []) {
    const m = byEdge.get(e.id);
    if (!m) continue;
    const points: Point[] = [];
    for (const s of e.sections ?? []) {
      points.push(s.startPoint, ...(s.bendPoints ?? []), s.endPoint);
    }
    const l = e.labels?.[0];
    edgeGeoms.push({
      id: m.id,
      source: m.source,
      target: m.target,
      label: m.label,
      points,
      labelBox: l ? { x: l.x ?? 0, y: l.y ?? 0, w: l.width ?? 0, h: l.height ?? 0 } : null,
    });
  }
  let w = out.width ?? 200;
  const h = out.height ?? 100;
  w = Math.max(w, textWidth(lane.name, 15, "600") + 80, 180);
  return { lane, x: 0, y: 0, w, h: h + HEADER_H, headerH: HEADER_H, nodes, edges: edgeGeoms };
}

/**
 * ELK's layout of `graph`; a fresh layout (no hints: they are this page's own drawing) is first
 * looked up in the studio server's layout cache under the hash of exactly this input, and what
 * ELK makes is sent there (src/draw/layout-store.ts, docs/studio.md "Layout cache").
 */
async function laidOut(graph: ElkNode, keep: boolean): Promise<ElkNode> {
  const key = keep ? layoutKey(graph) : null;
  const stored = key ? await storedLayout(key, graph) : null;
  if (stored) {
    warmLater(key as string, graph, stored);
    return stored;
  }
  layoutStats.elk += 1;
  const out = await engine().layout(graph);
  if (key) keepLayout(key, out);
  return out;
}

let warming = false;
/**
 * Once per page, a second after a lane came from the layout cache: ELK lays that lane out in the
 * background, so that the first edit does not pay ELK's cold start (its first layout of a big
 * lane takes ~2.5 x a warm one), and its answer is compared with the cached one: a difference (the
 * cache would not draw what ELK draws) is said in the console, counted, and ELK's layout replaces
 * the entry in the user's cache, which is looked up before a shipped file.
 */
function warmLater(key: string, graph: ElkNode, stored: ElkNode): void {
  if (warming) return;
  warming = true;
  setTimeout(() => {
    engine()
      .layout(graph)
      .then((out) => {
        layoutStats.warmed += 1;
        if (JSON.stringify(keptPart(out)) !== JSON.stringify(keptPart(stored))) {
          layoutStats.differ += 1;
          console.warn("studio: a cached layout differs from ELK's; ELK's is kept for the next open");
          keepLayout(key, out);
        }
      })
      .catch(() => undefined);
  }, 1000);
}

// Layouts by diagram text: a reconnect or a recompile that left a diagram alone reuses its layout.
const cache = new Map<string, Promise<Layout>>();
function cached<T extends Layout>(key: string, make: () => Promise<T>): Promise<T> {
  let p = cache.get(key);
  if (!p) {
    if (cache.size > 64) cache.clear();
    p = make();
    cache.set(key, p);
    p.catch(() => cache.delete(key));
  }
  return p as Promise<T>;
}

/** Positions the user chose in one diagram ("<lane>/<node>" or a component's name -> [x, y]). */
export type Positions = Record<string, [number, number]>;

// Lanes are laid out one by one and cached by their own text: an edit relays out only its lane
// (and an undo finds the drawing from before the edit).
const laneCache = new Map<string, Promise<LaneGeom>>();
// The last drawing of each lane ("<diagram>/<lane>"): an edited lane is laid out again with its
// nodes' places there as hints. Kept for the page's life (a reload lays the diagram out afresh).
const lastLane = new Map<string, Promise<LaneGeom>>();

// Each lane's text, made once per lane object (an answer's lanes are new objects; a 2 000-node
// diagram's text takes milliseconds to make, and the caches below look it up three times).
const laneTexts = new WeakMap<ModelLane, string>();
function laneText(lane: ModelLane): string {
  let text = laneTexts.get(lane);
  if (text === undefined) {
    text = JSON.stringify(lane);
    laneTexts.set(lane, text);
  }
  return text;
}

function laneLayout(
  diagram: string,
  lane: ModelLane,
  index: number,
  before: ModelDiagram | undefined,
): Promise<LaneGeom> {
  const key = laneText(lane);
  let p = laneCache.get(key);
  if (!p) {
    if (laneCache.size > 4096) laneCache.clear();
    // a renamed lane is found at its index in the diagram as drawn before
    const was =
      lastLane.get(`${diagram}/${lane.name}`) ??
      (before?.lanes[index] && !before.lanes.some((l) => l.name === lane.name)
        ? lastLane.get(`${diagram}/${before.lanes[index].name}`)
        : undefined);
    p = was
      ? was.then(
          // a region opened or closed (draw/regions.ts): laid out afresh, as the lane opens
          (g) => sameShape(g, lane) ?? (sameRegions(g.lane, lane) ? relayoutLane(lane, g) : layoutLane(lane)),
          () => layoutLane(lane),
        )
      : layoutLane(lane);
    laneCache.set(key, p);
    p.catch(() => laneCache.delete(key));
  }
  lastLane.set(`${diagram}/${lane.name}`, p);
  return p;
}

/** Whether two drawings of a lane collapse the same regions. */
function sameRegions(a: ModelLane, b: ModelLane): boolean {
  const boxes = (l: ModelLane): string =>
    l.nodes
      .filter((n) => n.kind === REGION_KIND)
      .map((n) => n.id)
      .join("\n");
  return boxes(a) === boxes(b);
}

/** The width ELK reserves for a flow's guard label. */
const guardWidth = (label: string): number => textWidth(`${shortGuard(label)}  ×8888`, SMALL_PX) + 8;

/**
 * The last drawing of a lane when the edit left its shape alone — the same nodes and flows, each
 * node as big as before, each guard fitting its box (a value, a call or a guard changed): that geometry with
 * the new texts, without asking ELK again (~100 ms in its worker for a lane of 100 nodes, the
 * most of an edit's drawing); null when anything moved or grew.
 */
function sameShape(g: LaneGeom, lane: ModelLane): LaneGeom | null {
  const known = new Set(lane.nodes.map((n) => n.id));
  const flows = lane.edges.filter((e) => known.has(e.source) && known.has(e.target));
  if (g.lane.name !== lane.name || g.nodes.length !== lane.nodes.length || g.edges.length !== flows.length) return null;
  const byId = new Map(lane.nodes.map((n) => [n.id, n]));
  const nodes: NodeBox[] = [];
  for (const nb of g.nodes) {
    const n = byId.get(nb.node.id);
    if (!n || n.kind !== nb.node.kind) return null;
    if (n.label !== nb.node.label) {
      const size = nodeSize(n);
      if (size.w !== nb.w || size.h !== nb.h) return null;
    }
    nodes.push({ ...nb, node: n });
  }
  const flowById = new Map(flows.map((e) => [e.id, e]));
  const edges: EdgeGeom[] = [];
  for (const e of g.edges) {
    const f = flowById.get(e.id);
    if (!f || f.source !== e.source || f.target !== e.target || !f.label !== !e.label) return null;
    // a guard as wide or narrower fits the box ELK reserved for the old one (centred in it)
    if (f.label !== e.label && (!e.labelBox || guardWidth(f.label) > e.labelBox.w)) return null;
    edges.push({ ...e, label: f.label });
  }
  return { ...g, lane, nodes, edges };
}

/** How far (px) ELK may move a node drawn before when it lays out an edited lane again. */
export const STICKY_PX = 20;

/**
 * An edited lane: ELK lays it out again with the last drawing as hints; when that moves a node
 * drawn before by more than STICKY_PX (ELK's interactive layering does not reproduce a big lane
 * with loops: the car's main moved by hundreds of px), the nodes drawn before keep their places
 * and flows, and only the new nodes and flows are placed and routed.
 */
async function relayoutLane(lane: ModelLane, g: LaneGeom): Promise<LaneGeom> {
  const old = matchOld(g, lane);
  // an end that a new flow enters from below (a lane built in the page: its end was drawn under
  // its start) goes below the lane's content, as a new node would: flows go down
  const was = new Set(g.edges.map((e) => `${e.source}>${e.target}`));
  for (const e of lane.edges) {
    const a = old.get(e.source);
    const b = old.get(e.target);
    if (a && b && b.node.kind === "end" && b.y < a.y + a.h && !was.has(`${a.node.id}>${b.node.id}`))
      old.delete(e.target);
  }
  const hints = hintsFrom(g, lane, old);
  const fresh = await layoutLane(lane, hints);
  const far = fresh.nodes.some((nb) => {
    const o = old.get(nb.node.id);
    return o !== undefined && Math.max(Math.abs(o.x - nb.x), Math.abs(o.y - nb.y)) > STICKY_PX;
  });
  return far ? keepPlaces(fresh, g, old, hints) : fresh;
}

/** The nodes drawn before: each node's own box, or a renamed one's (by its place in the list). */
function matchOld(g: LaneGeom, lane: ModelLane): Map<string, NodeBox> {
  const was = new Map(g.nodes.map((nb) => [nb.node.id, nb]));
  const ids = new Set(lane.nodes.map((n) => n.id));
  const match = new Map<string, NodeBox>();
  lane.nodes.forEach((n, i) => {
    let nb = was.get(n.id);
    const o = g.lane.nodes[i];
    if (!nb && o && o.kind === n.kind && !ids.has(o.id)) nb = was.get(o.id);
    if (nb) match.set(n.id, nb);
  });
  return match;
}

/** `fresh` with the nodes of `g` back at their places, their flows as drawn there. */
function keepPlaces(fresh: LaneGeom, g: LaneGeom, old: Map<string, NodeBox>, hints: Hints): LaneGeom {
  const nodes = fresh.nodes.map((nb) => {
    const p = old.get(nb.node.id) ?? hints.get(nb.node.id);
    if (!p) return nb;
    const dx = p.x - nb.x;
    const dy = p.y - nb.y;
    return { ...nb, x: p.x, y: p.y, statsX: nb.statsX + dx, statsY: nb.statsY + dy };
  });
  const box = new Map(nodes.map((nb) => [nb.node.id, nb]));
  const oldId = new Map([...old].map(([id, nb]) => [id, nb.node.id]));
  const oldEdges = new Map(g.edges.map((e) => [`${e.source}>${e.target}`, e]));
  const same = (id: string): boolean => {
    const a = box.get(id);
    const o = old.get(id);
    return !!a && !!o && a.w === o.w && a.h === o.h;
  };
  const kept = new Set<string>();
  const edges = fresh.edges.map((e) => {
    const o = oldEdges.get(`${oldId.get(e.source)}>${oldId.get(e.target)}`);
    if (!o || !same(e.source) || !same(e.target) || o.label !== e.label) return e;
    kept.add(e.id);
    return { ...e, points: o.points, labelBox: o.labelBox };
  });
  return grown(
    fresh,
    g,
    nodes,
    rerouteAll(edges, (e) => !kept.has(e.id), box, nodes),
  );
}

/**
 * The places of a lane's nodes in its last drawing (`old`); a new node goes below the lane's
 * content (a layer of its own: the nodes drawn before keep theirs), under its first drawn
 * predecessor.
 */
function hintsFrom(g: LaneGeom, lane: ModelLane, old: Map<string, NodeBox>): Hints {
  const hints: Hints = new Map([...old].map(([id, nb]) => [id, { x: nb.x, y: nb.y }]));
  let bottom = 0;
  for (const nb of g.nodes) bottom = Math.max(bottom, nb.y + nb.h);
  for (const n of lane.nodes) {
    if (hints.has(n.id)) continue;
    const from = lane.edges.map((e) => (e.target === n.id ? hints.get(e.source) : undefined)).find((p) => p);
    // below the lane's content: a layer of its own, so the nodes drawn before keep theirs
    bottom += 40;
    hints.set(n.id, { x: from ? from.x : 24, y: bottom });
    bottom += nodeSize(n).h;
  }
  return hints;
}

// The last version of each activity diagram laid out (to find a renamed lane's last drawing).
const lastDiagram = new Map<string, ModelDiagram>();

export function layoutActivity(d: ModelDiagram, positions: Positions = {}): Promise<ActivityLayout> {
  const mine = Object.entries(positions).filter(([k]) => d.lanes.some((l) => k.startsWith(`${l.name}/`)));
  const before = lastDiagram.get(d.id);
  lastDiagram.set(d.id, d);
  const key = `a${JSON.stringify([{ ...d, lanes: d.lanes.length }, mine])}${d.lanes.map(laneText).join("\n")}`;
  const out = cached(key, () => layoutActivityNow(d, positions, before));
  // drawn from the cache (an undo): its lanes are the last drawings now
  for (const l of d.lanes) {
    const p = laneCache.get(laneText(l));
    if (p) lastLane.set(`${d.id}/${l.name}`, p);
  }
  return out;
}

export function layoutComponents(model: ModelView, positions: Positions = {}): Promise<ComponentLayout> {
  return cached(`c${JSON.stringify([model.name, model.components, model.links, positions])}`, () =>
    layoutComponentsNow(model, positions),
  );
}

/** A lane with the user's positions applied: moved nodes at their places, the nodes laid out
 * automatically moved down clear of them, the flows of what moved routed again (around the nodes),
 * the lane grown to fit. */
function placeLane(auto: LaneGeom, positions: Positions): LaneGeom {
  const name = auto.lane.name;
  const pinned = new Set<string>();
  let nodes = auto.nodes.map((nb) => {
    const p = positions[`${name}/${nb.node.id}`];
    if (!p) return nb;
    pinned.add(nb.node.id);
    const dx = p[0] - nb.x;
    const dy = p[1] - nb.y;
    return { ...nb, x: p[0], y: p[1], statsX: nb.statsX + dx, statsY: nb.statsY + dy };
  });
  if (!pinned.size) return auto;
  const shift = clearOfPinned(nodes, pinned);
  nodes = nodes.map((nb) => {
    const dy = shift.get(nb.node.id) ?? 0;
    return dy ? { ...nb, y: nb.y + dy, statsY: nb.statsY + dy } : nb;
  });
  const box = new Map(nodes.map((nb) => [nb.node.id, nb]));
  const moved = (e: EdgeGeom): boolean =>
    pinned.has(e.source) || pinned.has(e.target) || (shift.get(e.source) ?? 0) !== (shift.get(e.target) ?? 0);
  const edges = auto.edges.map((e) => {
    const dy = shift.get(e.source) ?? 0;
    if (moved(e) || !dy) return e;
    // both ends moved down together: the flow moves with them
    return {
      ...e,
      points: e.points.map((p) => ({ x: p.x, y: p.y + dy })),
      labelBox: e.labelBox ? { ...e.labelBox, y: e.labelBox.y + dy } : null,
    };
  });
  return grown(auto, auto, nodes, rerouteAll(edges, moved, box, nodes));
}

/** Room kept between a node placed by the user and the nodes laid out around it (px). */
export const PINNED_GAP = 24;

/** What a node takes in its lane: its box, and the stats written beside it (small nodes). */
export function nodeExtent(nb: NodeBox): Rect {
  if (nb.statsInside) return { x: nb.x, y: nb.y, w: nb.w, h: nb.h };
  const right = nb.statsX + STATS2_W();
  const top = Math.min(nb.y, nb.statsY - 12);
  const bottom = Math.max(nb.y + nb.h, nb.statsY + 18);
  return { x: nb.x, y: top, w: right - nb.x, h: bottom - top };
}

function overlaps(a: Rect, b: Rect): boolean {
  return a.x < b.x + b.w && b.x < a.x + a.w && a.y < b.y + b.h && b.y < a.y + a.h;
}

/**
 * How far (px, down) each node laid out automatically moves so that none overlaps a node the user
 * placed (`pinned`): the first one that does moves below it, with every node at or below it, so
 * the automatic layout's order top to bottom is kept (its flows still go down).
 */
function clearOfPinned(nodes: NodeBox[], pinned: Set<string>): Map<string, number> {
  const fixed = nodes.filter((nb) => pinned.has(nb.node.id)).map((nb) => grow(nodeExtent(nb), PINNED_GAP / 2));
  const free = nodes
    .filter((nb) => !pinned.has(nb.node.id))
    .map((nb) => ({ id: nb.node.id, r: grow(nodeExtent(nb), PINNED_GAP / 2) }))
    .sort((p, q) => p.r.y - q.r.y);
  const shift = new Map<string, number>();
  for (let k = 0; k < free.length; k++) {
    const hit = fixed.find((f) => overlaps(f, free[k].r));
    if (!hit) continue;
    const top = free[k].r.y;
    const dy = hit.y + hit.h - top;
    for (const f of free) {
      if (f.r.y < top - 0.5) continue;
      f.r = { ...f.r, y: f.r.y + dy };
      shift.set(f.id, (shift.get(f.id) ?? 0) + dy);
    }
    k = -1; // look again from the top: a moved node may meet another placed node
  }
  return shift;
}

/** How far a rerouted flow keeps from the nodes it passes (px); it leaves and enters straight for a bit more. */
const FLOW_CLEARANCE = 10;

/**
 * An orthogonal route from a's bottom to b's top (from a's side to b's side when b is beside a;
 * out of a's side and into b's side when b is above a: a flow back), around the lane's other
 * nodes and the stats written beside them.
 */
function routeEdge(a: NodeBox, b: NodeBox, nodes: NodeBox[], avoid: Point[][]): Point[] {
  const ax = a.x + a.w / 2;
  const bx = b.x + b.w / 2;
  // a small node's stats are written on its right: its flows back leave and enter on its left
  const side = (nb: NodeBox): Dir => (nb.statsInside ? "E" : "W");
  const lead = FLOW_CLEARANCE + 4;
  let from: Dir;
  let into: Dir;
  if (b.y >= a.y + a.h + 2 * lead + 4) {
    from = "S";
    into = "N";
  } else if (b.y + b.h + 12 <= a.y) {
    from = side(a);
    into = side(b);
  } else {
    // beside: out of the side that faces b, into b's top when it is lower (else its facing side)
    const right = bx > ax;
    from = right ? "E" : "W";
    into = b.y > a.y + a.h / 2 ? "N" : right ? "W" : "E";
  }
  const at = (nb: NodeBox, d: Dir): Point =>
    d === "S"
      ? { x: nb.x + nb.w / 2, y: nb.y + nb.h }
      : d === "N"
        ? { x: nb.x + nb.w / 2, y: nb.y }
        : d === "E"
          ? { x: nb.x + nb.w, y: nb.y + nb.h / 2 }
          : { x: nb.x, y: nb.y + nb.h / 2 };
  const keepOut: Rect[] = [];
  for (const nb of nodes) {
    keepOut.push(grow({ x: nb.x, y: nb.y, w: nb.w, h: nb.h }, FLOW_CLEARANCE));
    if (!nb.statsInside && nb !== a && nb !== b) keepOut.push(grow(nodeExtent(nb), 2));
  }
  const found = route(at(a, from), from, at(b, into), into, keepOut, {
    lead,
    avoid,
    bounds: { x: 2, y: 0, w: 1e6, h: 1e6 },
  });
  if (found) return found;
  // walled in: the plain line (drawn over, never lost)
  if (from === "S")
    return [
      { x: ax, y: a.y + a.h },
      { x: ax, y: (a.y + a.h + b.y) / 2 },
      { x: bx, y: (a.y + a.h + b.y) / 2 },
      { x: bx, y: b.y },
    ];
  return [at(a, from), at(b, into)];
}

async function layoutActivityNow(
  d: ModelDiagram,
  positions: Positions,
  before: ModelDiagram | undefined,
): Promise<ActivityLayout> {
  const auto = await Promise.all(d.lanes.map((l, i) => laneLayout(d.id, l, i, before)));
  // copies: the cached lane geometry is shared and must not be changed
  const lanes = auto.map((l) => placeLane({ ...l }, positions));
  let x = 0;
  let height = 0;
  for (const l of lanes) height = Math.max(height, l.h);
  for (const l of lanes) {
    l.x = x;
    l.y = 0;
    // Centre the lane's content in its column.
    x += l.w + LANE_GAP;
    l.h = height;
  }
  return { kind: "activity", diagram: d, width: Math.max(x, 1), height: Math.max(height, 1), lanes };
}

// ---- component diagram ----

export const COMP_STATE_LINES = 6;
export interface PortGeom {
  name: string;
  feature: string;
  x: number;
  y: number;
  w: number;
  h: number;
  side: "EAST" | "WEST";
  labelX: number;
  labelY: number;
}
export interface ComponentGeom {
  name: string;
  x: number;
  y: number;
  w: number;
  h: number;
  ports: PortGeom[];
}
export interface LinkGeom {
  id: string;
  points: Point[];
  label: string;
  labelX: number;
  labelY: number;
}
export interface ComponentLayout {
  kind: "components";
  width: number;
  height: number;
  components: ComponentGeom[];
  links: LinkGeom[];
  orch: { x: number; y: number; w: number; h: number };
}

// Where each component of a model was drawn last (ELK's place, or the one it kept), and what it
// took there (its box with its ports' labels): an edit that adds, removes or links a component
// leaves the others where they are (ELK alone would reshuffle them all); only a new component, or
// one whose labels now reach into another, gets a new place. Kept for the page's life (a reload
// lays the diagram out afresh).
const lastPlaces = new Map<string, Map<string, { at: Point; extent: string }>>();

/** A component as ELK laid it out: its box and what it takes with its ports and their labels
 * (`extent`, relative to the box's corner). */
interface CompBox {
  id: string;
  x: number;
  y: number;
  w: number;
  h: number;
  extent: Rect;
}

/** Room kept between the components' boxes and labels when one is placed anew (px). */
const COMP_GAP = 40;

/**
 * The places of the components: the user's (`pinned`), then those kept from the last drawing that
 * have room there, then the others at ELK's place if that has room, else below everything.
 */
function stickyPlaces(modelName: string, elkBoxes: CompBox[], pinned: Positions): Positions {
  const before = lastPlaces.get(modelName);
  const kept: Positions = {};
  const now = new Map<string, { at: Point; extent: string }>();
  const sig = (b: CompBox): string => JSON.stringify(b.extent);
  // (a first drawing with components the user placed: the others go where they have room too)
  if ((before && elkBoxes.some((b) => before.has(b.id))) || Object.keys(pinned).length) {
    const taken: Rect[] = [];
    const room = (b: CompBox, x: number, y: number): boolean => {
      const r = grow({ x: x + b.extent.x, y: y + b.extent.y, w: b.extent.w, h: b.extent.h }, COMP_GAP / 2);
      return !taken.some((t) => overlaps(t, r));
    };
    const take = (b: CompBox, x: number, y: number): void => {
      kept[b.id] = [x, y];
      taken.push(grow({ x: x + b.extent.x, y: y + b.extent.y, w: b.extent.w, h: b.extent.h }, COMP_GAP / 2));
    };
    for (const b of elkBoxes) if (pinned[b.id]) take(b, pinned[b.id][0], pinned[b.id][1]);
    const unchanged = (b: CompBox): boolean => before?.get(b.id)?.extent === sig(b);
    // the components that look as before keep their places first; one that grew (a new port's
    // label) keeps its place if it still has room there
    const order = [...elkBoxes.filter((b) => unchanged(b)), ...elkBoxes.filter((b) => !unchanged(b))];
    const later: CompBox[] = [];
    for (const b of order) {
      if (pinned[b.id]) continue;
      const p = before?.get(b.id)?.at;
      if (p && room(b, p.x, p.y)) take(b, p.x, p.y);
      else later.push(b);
    }
    for (const b of later) {
      if (room(b, b.x, b.y)) {
        take(b, b.x, b.y);
        continue;
      }
      const bottom = Math.max(0, ...taken.map((t) => t.y + t.h));
      take(b, 30 - b.extent.x, bottom + COMP_GAP / 2 - b.extent.y);
    }
  }
  for (const b of elkBoxes) {
    const k = kept[b.id] ?? pinned[b.id];
    now.set(b.id, { at: k ? { x: k[0], y: k[1] } : { x: b.x, y: b.y }, extent: sig(b) });
  }
  lastPlaces.set(modelName, now);
  return kept;
}

/** How far a link keeps from the components it passes (px). */
const LINK_CLEARANCE = 12;

/**
 * A link routed around the components (and their ports' labels) from its source port's outer
 * side to its target port's: the drawing once components keep places ELK did not give them.
 */
function routeLink(
  id: string,
  from: PortGeom,
  to: PortGeom,
  components: ComponentGeom[],
  orch: Rect,
  avoid: Point[][],
): LinkGeom {
  const end = (p: PortGeom): { at: Point; dir: Dir } =>
    p.side === "EAST"
      ? { at: { x: p.x + p.w, y: p.y + p.h / 2 }, dir: "E" }
      : { at: { x: p.x, y: p.y + p.h / 2 }, dir: "W" };
  const a = end(from);
  const b = end(to);
  const keepOut: Rect[] = [grow(orch, LINK_CLEARANCE)];
  for (const c of components) {
    keepOut.push(grow({ x: c.x, y: c.y, w: c.w, h: c.h }, LINK_CLEARANCE));
    for (const p of c.ports) {
      const label = portLabelBox(p);
      if (p === from || p === to) {
        // its own port's label is under the line where it leaves: the line may not turn down through it
        const top = Math.max(label.y, p.y + p.h / 2 + 1);
        keepOut.push({ ...label, y: top, h: Math.max(0, label.y + label.h - top) });
      } else keepOut.push(grow(label, 3));
    }
  }
  const points = route(a.at, a.dir, b.at, b.dir, keepOut, {
    lead: LINK_CLEARANCE + 4,
    avoid,
    bounds: { x: 0, y: 0, w: 1e6, h: 1e6 },
  }) ?? [a.at, { x: (a.at.x + b.at.x) / 2, y: a.at.y }, { x: (a.at.x + b.at.x) / 2, y: b.at.y }, b.at];
  const mid = middle(points);
  const w = textWidth(id, SMALL_PX);
  return mid.horizontal
    ? { id, points, label: id, labelX: mid.x - w / 2, labelY: mid.y - 4 }
    : { id, points, label: id, labelX: mid.x + 4, labelY: mid.y + 4 };
}

/** The box a port's label takes (its text's baseline is labelY). */
export function portLabelBox(p: PortGeom): Rect {
  return { x: p.labelX, y: p.labelY - 11, w: textWidth(`${p.name} → ${p.feature}`, SMALL_PX), h: 14 };
}

async function layoutComponentsNow(model: ModelView, userPositions: Positions): Promise<ComponentLayout> {
  const incoming = new Set(model.links.map((l) => `${l.target.component}.${l.target.port}`));
  const orchW = 420;
  const orchH = 70;
  const children: ElkNode[] = model.components.map((c) => {
    const lines = [
      textWidth(c.name, 15, "600") + 40,
      textWidth(`${c.impl} · ${c.service} · ${c.driver} → pigpio`, SMALL_PX) + 24, // (+ the driver it runs)
      textWidth(`features: ${c.features.join(", ")}`, SMALL_PX) + 24,
      240,
    ];
    const ports = Object.entries(c.ports).map(([port, feature]) => {
      const side = incoming.has(`${c.name}.${port}`) ? "WEST" : "EAST";
      const text = `${port} → ${feature}`;
      return {
        id: `${c.name}.${port}`,
        width: 10,
        height: 10,
        labels: [{ id: `${c.name}.${port}#l`, text, width: textWidth(text, SMALL_PX), height: 14 }],
        layoutOptions: { "elk.port.side": side },
      };
    });
    return {
      id: c.name,
      width: Math.max(...lines),
      height: 78 + 15 * COMP_STATE_LINES,
      ports,
      layoutOptions: { "elk.portConstraints": "FIXED_SIDE", "elk.portLabels.placement": "OUTSIDE" },
    };
  });
  const edges: ElkExtendedEdge[] = model.links.map((l) => ({
    id: l.id,
    sources: [`${l.source.component}.${l.source.port}`],
    targets: [`${l.target.component}.${l.target.port}`],
    labels: [{ id: `${l.id}#l`, text: l.id, width: textWidth(l.id, SMALL_PX) + 6, height: 14 }],
  }));
  const graph: ElkNode = {
    id: "root",
    layoutOptions: {
      "elk.algorithm": "layered",
      "elk.direction": "RIGHT",
      "elk.edgeRouting": "ORTHOGONAL",
      "elk.spacing.nodeNode": "40",
      "elk.layered.spacing.nodeNodeBetweenLayers": "90",
      "elk.spacing.componentComponent": "48",
      "elk.padding": `[top=${orchH + 50},left=30,bottom=30,right=30]`,
      "elk.json.edgeCoords": "ROOT",
      "elk.json.shapeCoords": "ROOT",
      "elk.layered.considerModelOrder.strategy": "NODES_AND_EDGES",
      "elk.aspectRatio": "2.0",
    },
    children,
    edges,
  };
  const out = await engine().layout(graph);
  const elkBoxes: CompBox[] = (out.children ?? []).map((c) => {
    const x = c.x ?? 0;
    const y = c.y ?? 0;
    const w = c.width ?? 200;
    const h = c.height ?? 100;
    // the box with its ports and their labels (ELK's coordinates are the root's)
    let x0 = x;
    let y0 = y;
    let x1 = x + w;
    let y1 = y + h;
    for (const p of c.ports ?? []) {
      const l = p.labels?.[0];
      for (const r of [
        { x: p.x ?? x, y: p.y ?? y, w: p.width ?? 0, h: p.height ?? 0 },
        ...(l ? [{ x: l.x ?? x, y: l.y ?? y, w: l.width ?? 0, h: l.height ?? 0 }] : []),
      ]) {
        x0 = Math.min(x0, r.x);
        y0 = Math.min(y0, r.y);
        x1 = Math.max(x1, r.x + r.w);
        y1 = Math.max(y1, r.y + r.h);
      }
    }
    return { id: c.id, x, y, w, h, extent: { x: x0 - x, y: y0 - y, w: x1 - x0, h: y1 - y0 } };
  });
  // the places the user chose (the layout file), and those kept from the last drawing
  const mine: Positions = Object.fromEntries(
    Object.entries(userPositions).filter(([id]) => elkBoxes.some((b) => b.id === id)),
  );
  const positions: Positions = { ...stickyPlaces(model.name, elkBoxes, mine), ...mine };
  for (const [id, p] of Object.entries(positions)) {
    const b = elkBoxes.find((x) => x.id === id);
    if (b && Math.abs(b.x - p[0]) < 0.5 && Math.abs(b.y - p[1]) < 0.5) delete positions[id]; // where ELK put it
  }
  const components: ComponentGeom[] = [];
  for (const c of out.children ?? []) {
    const m = model.components.find((mc) => mc.name === c.id);
    if (!m) continue;
    const pos = positions[c.id];
    const dx = pos ? pos[0] - (c.x ?? 0) : 0;
    const dy = pos ? pos[1] - (c.y ?? 0) : 0;
    const x = (c.x ?? 0) + dx;
    const y = (c.y ?? 0) + dy;
    const ports: PortGeom[] = (c.ports ?? []).map((p) => {
      const name = p.id.slice(c.id.length + 1);
      // elk.json.shapeCoords ROOT: ports and their labels are in root coordinates too.
      const px = (p.x ?? x - dx) + dx;
      const py = (p.y ?? y - dy) + dy;
      const l = p.labels?.[0];
      const side = incoming.has(p.id) ? "WEST" : "EAST";
      return {
        name,
        feature: m.ports[name] ?? "",
        x: px,
        y: py,
        w: p.width ?? 10,
        h: p.height ?? 10,
        side,
        labelX: l && l.x !== undefined ? l.x + dx : px + 14,
        labelY: l && l.y !== undefined ? l.y + dy + 11 : py - 4,
      };
    });
    components.push({ name: c.id, x, y, w: c.width ?? 200, h: c.height ?? 100, ports });
  }
  const portAt = new Map<string, PortGeom>();
  for (const c of components) for (const p of c.ports) portAt.set(`${c.name}.${p.name}`, p);
  const orch = { x: 30, y: 24, w: orchW, h: orchH };
  // ELK's routes fit ELK's places: once a component is elsewhere, every link is routed anew
  const elsewhere = Object.keys(positions).length > 0;
  const drawn: Point[][] = [];
  const links: LinkGeom[] = (out.edges ?? []).map((e) => {
    const link = model.links.find((l) => l.id === e.id);
    const from = link ? portAt.get(`${link.source.component}.${link.source.port}`) : undefined;
    const to = link ? portAt.get(`${link.target.component}.${link.target.port}`) : undefined;
    if (elsewhere && from && to) {
      const routed = routeLink(e.id, from, to, components, orch, drawn);
      drawn.push(routed.points);
      return routed;
    }
    const points: Point[] = [];
    for (const s of e.sections ?? []) points.push(s.startPoint, ...(s.bendPoints ?? []), s.endPoint);
    const l = e.labels?.[0];
    return {
      id: e.id,
      points,
      label: e.id,
      labelX: l?.x ?? points[0]?.x ?? 0,
      labelY: (l?.y ?? points[0]?.y ?? 0) + 11,
    };
  });
  let width = Math.max(out.width ?? 300, orchW + 60);
  let height = out.height ?? 200;
  // the components with their ports' labels, and a margin (no more: a wider extent opened the
  // diagram smaller than needed, or cut at the canvas's right edge)
  for (const c of components) {
    const e = elkBoxes.find((b) => b.id === c.name)?.extent;
    width = Math.max(width, c.x + Math.max(c.w, e ? e.x + e.w : 0) + 30);
    height = Math.max(height, c.y + Math.max(c.h, e ? e.y + e.h : 0) + 30);
  }
  for (const l of links) {
    for (const p of l.points) {
      width = Math.max(width, p.x + 30);
      height = Math.max(height, p.y + 30);
    }
  }
  return {
    kind: "components",
    width,
    height,
    components,
    links,
    orch,
  };
}

export type Layout = ActivityLayout | ComponentLayout;

/** An edge drawn again between its nodes' new boxes, around the lane's other nodes and beside the
 * flows drawn already (`routeEdge`). */
function rerouted(e: EdgeGeom, box: Map<string, NodeBox>, nodes: NodeBox[], avoid: Point[][]): EdgeGeom {
  const a = box.get(e.source);
  const b = box.get(e.target);
  if (!a || !b) return e;
  const points = routeEdge(a, b, nodes, avoid);
  const mid = middle(points);
  const labelBox = e.labelBox ? { ...e.labelBox, x: mid.x - e.labelBox.w / 2, y: mid.y - e.labelBox.h / 2 } : null;
  return { ...e, points, labelBox };
}

/**
 * `edges` with those that must be drawn again (`again`: their nodes moved, or they would run
 * through another node) routed anew one by one, each beside the flows drawn before it.
 */
function rerouteAll(
  edges: EdgeGeom[],
  again: (e: EdgeGeom) => boolean,
  box: Map<string, NodeBox>,
  nodes: NodeBox[],
): EdgeGeom[] {
  const redo = edges.map(
    (e) =>
      again(e) ||
      nodes.some(
        (nb) =>
          nb.node.id !== e.source &&
          nb.node.id !== e.target &&
          pathCrosses(grow({ x: nb.x, y: nb.y, w: nb.w, h: nb.h }, -1), e.points),
      ),
  );
  const out = edges.slice();
  for (let i = 0; i < out.length; i++) {
    if (!redo[i]) continue;
    const avoid = out.filter((_, k) => k !== i && (!redo[k] || k < i)).map((x) => x.points);
    out[i] = rerouted(out[i], box, nodes, avoid);
  }
  return out;
}

/** `lane` with `nodes` and `edges`, at least as big as `size` and big enough for every node. */
function grown(lane: LaneGeom, size: LaneGeom, nodes: NodeBox[], edges: EdgeGeom[]): LaneGeom {
  let w = size.w;
  let h = size.h - size.headerH;
  for (const nb of nodes) {
    w = Math.max(w, nb.x + nb.w + (nb.statsInside ? 24 : STATS2_W() + 24));
    h = Math.max(h, nb.y + nb.h + 24);
  }
  for (const e of edges) {
    for (const p of e.points) {
      w = Math.max(w, p.x + 16);
      h = Math.max(h, p.y + 16);
    }
  }
  return { ...lane, w, h: h + lane.headerH, nodes, edges };
}
