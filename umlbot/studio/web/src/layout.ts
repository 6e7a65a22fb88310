// Automatic layout with ELK (elkjs, run in its Web Worker). Activity diagrams: each lane is laid
// out on its own (layered, direction DOWN) and the lanes are placed side by side as columns with a
// header each; edges stay inside their lane. The component diagram is one layered graph (RIGHT)
// with the link ports on the component boxes.

import ELK from "elkjs/lib/elk-api.js";
import type { ElkExtendedEdge, ElkNode } from "elkjs/lib/elk-api.js";
import type { ModelDiagram, ModelLane, ModelNode, ModelView } from "./types";

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
  void engine().knownLayoutAlgorithms().catch(() => undefined);
}

export function textWidth(text: string, px: number, weight = "normal"): number {
  ctx.font = `${weight} ${px}px ${FONT}`;
  return Math.ceil(ctx.measureText(text).width);
}

export interface Point { x: number; y: number }
export interface NodeBox {
  node: ModelNode;
  x: number; y: number; w: number; h: number;
  statsX: number; statsY: number; statsInside: boolean;
}
export interface EdgeGeom {
  id: string; source: string; target: string; label: string;
  points: Point[];
  labelBox: { x: number; y: number; w: number; h: number } | null;
}
export interface LaneGeom {
  lane: ModelLane;
  x: number; y: number; w: number; h: number; // lane column incl. header
  headerH: number;
  nodes: NodeBox[];
  edges: EdgeGeom[];
}
export interface ActivityLayout { kind: "activity"; diagram: ModelDiagram; width: number; height: number; lanes: LaneGeom[] }

const HEADER_H = 34;
const LANE_GAP = 0;
const STATS_W = () => textWidth(STATS_SAMPLE, SMALL_PX);
// Stats beside a small node (start, end, fork, join, decision) take two lines.
export const STATS2_SAMPLE = "p50 888.8 · p99 888.8";
const STATS2_W = () => textWidth(STATS2_SAMPLE, SMALL_PX) + 4;

export function nodeSize(n: ModelNode): { w: number; h: number; statsInside: boolean } {
  const lw = textWidth(n.label, LABEL_PX);
  const sw = STATS_W();
  switch (n.kind) {
    case "start": return { w: 22, h: 22, statsInside: false };
    case "end": return { w: 26, h: 26, statsInside: false };
    case "fork":
    case "join": return { w: 110, h: 8, statsInside: false };
    case "decision": return { w: Math.max(64, lw + 44), h: 44, statsInside: false };
    case "datastore": return { w: Math.max(lw + 28, sw + 20, 150), h: 72, statsInside: true };
    case "send":
    case "accept": return { w: Math.max(lw + 56, sw + 36), h: 50, statsInside: true };
    default: return { w: Math.max(lw + 28, sw + 20), h: 50, statsInside: true };
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
  "elk.layered.considerModelOrder.strategy": "NODES_AND_EDGES",
  "elk.layered.cycleBreaking.strategy": "MODEL_ORDER",
  "elk.layered.nodePlacement.strategy": "NETWORK_SIMPLEX",
  "elk.padding": "[top=18,left=24,bottom=24,right=24]",
  "elk.json.edgeCoords": "ROOT",
  "elk.json.shapeCoords": "ROOT",
};

async function layoutLane(lane: ModelLane): Promise<LaneGeom> {
  const sizes = new Map<string, ReturnType<typeof nodeSize>>();
  const children: ElkNode[] = lane.nodes.map((n) => {
    const s = nodeSize(n);
    sizes.set(n.id, s);
    const child: ElkNode = { id: n.id, width: s.w, height: s.h };
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
        edge.labels = [{ id: `${e.id}#label`, text: e.label, width: textWidth(e.label + "  ×8888", SMALL_PX) + 8, height: 16 }];
      }
      return edge;
    });
  const graph: ElkNode = { id: "root", layoutOptions: LANE_OPTIONS, children, edges };
  const out = await engine().layout(graph);
  const nodes: NodeBox[] = [];
  const byId = new Map(lane.nodes.map((n) => [n.id, n]));
  for (const c of out.children ?? []) {
    const n = byId.get(c.id);
    if (!n) continue;
    const s = sizes.get(c.id)!;
    const x = c.x ?? 0;
    const y = c.y ?? 0;
    let statsX = x + s.w / 2;
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
      id: m.id, source: m.source, target: m.target, label: m.label, points,
      labelBox: l ? { x: l.x ?? 0, y: l.y ?? 0, w: l.width ?? 0, h: l.height ?? 0 } : null,
    });
  }
  let w = out.width ?? 200;
  const h = out.height ?? 100;
  w = Math.max(w, textWidth(lane.name, 15, "600") + 80, 180);
  return { lane, x: 0, y: 0, w, h: h + HEADER_H, headerH: HEADER_H, nodes, edges: edgeGeoms };
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

export function layoutActivity(d: ModelDiagram): Promise<ActivityLayout> {
  return cached("a" + JSON.stringify(d), () => layoutActivityNow(d));
}

export function layoutComponents(model: ModelView): Promise<ComponentLayout> {
  return cached("c" + JSON.stringify([model.name, model.components, model.links]), () => layoutComponentsNow(model));
}

async function layoutActivityNow(d: ModelDiagram): Promise<ActivityLayout> {
  const lanes = await Promise.all(d.lanes.map(layoutLane));
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
export interface PortGeom { name: string; feature: string; x: number; y: number; w: number; h: number; side: "EAST" | "WEST"; labelX: number; labelY: number }
export interface ComponentGeom { name: string; x: number; y: number; w: number; h: number; ports: PortGeom[] }
export interface LinkGeom { id: string; points: Point[]; label: string; labelX: number; labelY: number }
export interface ComponentLayout {
  kind: "components"; width: number; height: number;
  components: ComponentGeom[]; links: LinkGeom[]; orch: { x: number; y: number; w: number; h: number };
}

async function layoutComponentsNow(model: ModelView): Promise<ComponentLayout> {
  const incoming = new Set(model.links.map((l) => `${l.target.component}.${l.target.port}`));
  const orchW = 420;
  const orchH = 70;
  const children: ElkNode[] = model.components.map((c) => {
    const lines = [
      textWidth(c.name, 15, "600") + 40,
      textWidth(`${c.impl} · ${c.service} · ${c.driver}`, SMALL_PX) + 24,
      textWidth(`features: ${c.features.join(", ")}`, SMALL_PX) + 24,
      240,
    ];
    const ports = Object.entries(c.ports).map(([port, feature]) => {
      const side = incoming.has(`${c.name}.${port}`) ? "WEST" : "EAST";
      const text = `${port} → ${feature}`;
      return {
        id: `${c.name}.${port}`, width: 10, height: 10,
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
  const components: ComponentGeom[] = [];
  for (const c of out.children ?? []) {
    const m = model.components.find((mc) => mc.name === c.id);
    if (!m) continue;
    const x = c.x ?? 0;
    const y = c.y ?? 0;
    const ports: PortGeom[] = (c.ports ?? []).map((p) => {
      const name = p.id.slice(c.id.length + 1);
      // elk.json.shapeCoords ROOT: ports and their labels are in root coordinates too.
      const px = p.x ?? x;
      const py = p.y ?? y;
      const l = p.labels?.[0];
      const side = incoming.has(p.id) ? "WEST" : "EAST";
      return {
        name, feature: m.ports[name] ?? "", x: px, y: py, w: p.width ?? 10, h: p.height ?? 10, side,
        labelX: l && l.x !== undefined ? l.x : px + 14,
        labelY: l && l.y !== undefined ? l.y + 11 : py - 4,
      };
    });
    components.push({ name: c.id, x, y, w: c.width ?? 200, h: c.height ?? 100, ports });
  }
  const links: LinkGeom[] = (out.edges ?? []).map((e) => {
    const points: Point[] = [];
    for (const s of e.sections ?? []) points.push(s.startPoint, ...(s.bendPoints ?? []), s.endPoint);
    const l = e.labels?.[0];
    return {
      id: e.id, points, label: e.id,
      labelX: l?.x ?? points[0]?.x ?? 0, labelY: (l?.y ?? points[0]?.y ?? 0) + 11,
    };
  });
  return {
    kind: "components",
    width: Math.max(out.width ?? 300, orchW + 60),
    height: out.height ?? 200,
    components, links,
    orch: { x: 30, y: 24, w: orchW, h: orchH },
  };
}

export type Layout = ActivityLayout | ComponentLayout;
