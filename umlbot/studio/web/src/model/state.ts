// The view state built from MonitorEvents: one code path for the live stream, the snapshot and
// replay. Every map holds immutable values, so a snapshot is a shallow copy of the maps; the only
// mutable data are the per-node duration histograms (durations.ts, bounded whatever the run's
// length), copied on write: a snapshot starts a new generation, and a histogram of an older one
// (shared with a snapshot) is cloned before it is added to.

import { Durations } from "./durations";
import type { ModelEdge, ModelNode, ModelView, MonitorEvent } from "./types";

export type Level = "info" | "warning" | "error";

export interface NodeStats {
  count: number;
  lastMs: number;
  durs: Durations; // p50/p99 over every run; shared with snapshots (copy on write)
  hasValue: boolean; // a datastore's value is known
  value: unknown; // datastore: its value; decision: the node it went to
  level: Level;
  message: string;
  lastIdx: number; // state clock when the node last completed (edge attribution)
}

export interface ComponentState {
  avail: "online" | "offline" | "unknown";
  impl: string;
  driver: string; // the driver its online status says the service runs ("" when not said)
  hasRetained: boolean;
  retained: unknown;
}

export interface CallRow {
  key: string;
  time: number;
  component: string;
  feature: string;
  args: unknown;
  ok: boolean | undefined;
  value: unknown;
  hasValue: boolean;
  error: string;
  latencyMs: number | undefined;
  detail: string; // the call as written (a replay's calls: their arguments are expressions)
}

export interface Snapshot {
  nodes: Map<string, NodeStats>;
  edges: Map<string, number>;
  trails: Map<string, string[]>;
  components: Map<string, ComponentState>;
  orch: { state: string; detail: string };
  calls: CallRow[];
  clock: number;
  traceSeq: number;
  traceLost: number;
  exitPayload: unknown;
}

export const TRAIL = 4; // current node + 3 fading
const CALLS_KEPT = 200;

export const nodeKey = (lane: string, node: string): string => `${lane}\u0000${node}`;
export const edgeKey = (lane: string, source: string, target: string): string =>
  `${lane}\u0000${source}\u0000${target}`;

interface LaneIndex {
  nodes: Map<string, ModelNode>;
  incoming: Map<string, ModelEdge[]>;
  outgoing: Map<string, string[]>;
}

export class ModelIndex {
  lanes = new Map<string, LaneIndex>();
  constructor(model: ModelView | null) {
    if (!model) return;
    for (const d of model.diagrams) {
      for (const lane of d.lanes) {
        const nodes = new Map<string, ModelNode>();
        const incoming = new Map<string, ModelEdge[]>();
        const outgoing = new Map<string, string[]>();
        for (const n of lane.nodes) nodes.set(n.id, n);
        for (const e of lane.edges) {
          const list = incoming.get(e.target);
          if (list) list.push(e);
          else incoming.set(e.target, [e]);
          const out = outgoing.get(e.source);
          if (out) out.push(e.target);
          else outgoing.set(e.source, [e.target]);
        }
        this.lanes.set(lane.name, { nodes, incoming, outgoing });
      }
    }
  }
}

/** The nodes that run after `node` completed in `lane`: a decision's branch, else every successor. */
export function nextNodes(index: ModelIndex, lane: string, node: string, stats: NodeStats | undefined): string[] {
  const li = index.lanes.get(lane);
  if (!li) return [];
  const kind = li.nodes.get(node)?.kind;
  if (kind === "end") return [];
  if (kind === "decision") return typeof stats?.value === "string" ? [stats.value] : [];
  return li.outgoing.get(node) ?? [];
}

export class StudioState {
  nodes = new Map<string, NodeStats>();
  edges = new Map<string, number>();
  trails = new Map<string, string[]>();
  components = new Map<string, ComponentState>();
  orch = { state: "unknown", detail: "" };
  calls: CallRow[] = []; // oldest first
  clock = 0;
  traceSeq = 0;
  traceLost = 0;
  exitPayload: unknown = undefined;
  private callSerial = 0;
  private gen = 0; // generation of the duration histograms this state may add to
  /** Counters of the histograms this generation owns (made or copied since the last snapshot):
   * what the next snapshot keeps beyond its maps. */
  ownedCounters = 0;

  // What changed since the renderer last looked.
  dirtyNodes = new Set<string>();
  dirtyEdges = new Set<string>();
  dirtyLanes = new Set<string>();
  dirtyComponents = new Set<string>();
  dirtyOrch = false;
  dirtyCalls = false;
  calledComponents = new Set<string>(); // components that got a call since the last frame
  allDirty = true;

  constructor(public index: ModelIndex) {}

  apply(e: MonitorEvent): void {
    switch (e.type) {
      case "trace":
        this.applyTrace(e);
        break;
      case "availability": {
        const name = e.component ?? "";
        const old = this.components.get(name);
        const avail = e.state === "online" ? "online" : e.state === "offline" ? "offline" : "unknown";
        this.components.set(name, {
          avail,
          impl: e.impl ?? old?.impl ?? "",
          driver: avail === "online" ? (e.driver ?? old?.driver ?? "") : "",
          hasRetained: old?.hasRetained ?? false,
          retained: old?.retained,
        });
        this.dirtyComponents.add(name);
        break;
      }
      case "state": {
        const name = e.component ?? "";
        const old = this.components.get(name);
        this.components.set(name, {
          avail: old?.avail ?? "unknown",
          impl: old?.impl ?? "",
          driver: old?.driver ?? "",
          hasRetained: true,
          retained: e.payload,
        });
        this.dirtyComponents.add(name);
        break;
      }
      case "orchestrator":
        this.orch = { state: e.state ?? "unknown", detail: e.detail ?? "" };
        this.dirtyOrch = true;
        break;
      case "exit":
        this.exitPayload = e.payload;
        this.dirtyOrch = true;
        break;
      case "call":
        this.applyCall(e);
        break;
      default:
        break;
    }
  }

  private applyTrace(e: MonitorEvent): void {
    const lane = e.lane ?? "";
    const node = e.node ?? "";
    const key = nodeKey(lane, node);
    const old = this.nodes.get(key);
    const d = typeof e.duration_ms === "number" ? e.duration_ms : 0;
    let durs = old ? old.durs : new Durations(this.gen);
    const before = old && durs.gen === this.gen ? durs.buckets : 0;
    if (durs.gen !== this.gen) durs = durs.clone(this.gen); // shared with a snapshot
    durs.add(d);
    this.ownedCounters += durs.buckets - before;
    const count = old ? old.count : 0;
    // The node's last run decides: a failed run is red, a warning amber, a good run clears it.
    let level: Level = "info";
    let message = "";
    if (e.level === "error" || (e.error !== undefined && e.error !== null)) {
      level = "error";
      message = e.error ?? e.detail ?? "error";
    } else if (e.level === "warning") {
      level = "warning";
      message = e.detail ?? "warning";
    }
    const hasValue = e.kind === "datastore" && "value" in e ? true : old ? old.hasValue : false;
    // a datastore's value, or the node a decision went to
    const value = (e.kind === "datastore" || e.kind === "decision") && "value" in e ? e.value : old?.value;

    // Edges: a decision says where it went; any other node was entered from the incoming edge
    // whose source completed most recently (a join from all of them).
    const laneIdx = this.index.lanes.get(lane);
    if (e.kind === "decision" && typeof e.value === "string") this.bump(edgeKey(lane, node, e.value));
    if (laneIdx) {
      const incoming = laneIdx.incoming.get(node);
      if (incoming?.length) {
        const kind = laneIdx.nodes.get(node)?.kind;
        if (kind === "join") {
          for (const edge of incoming) {
            const src = laneIdx.nodes.get(edge.source);
            if (src && src.kind !== "decision") this.bump(edgeKey(lane, edge.source, node));
          }
        } else {
          let best: ModelEdge | null = null;
          let bestIdx = -1;
          for (const edge of incoming) {
            const s = this.nodes.get(nodeKey(lane, edge.source));
            if (s && s.lastIdx > bestIdx) {
              bestIdx = s.lastIdx;
              best = edge;
            }
          }
          if (best && laneIdx.nodes.get(best.source)?.kind !== "decision") this.bump(edgeKey(lane, best.source, node));
        }
      }
    }

    this.clock += 1;
    this.nodes.set(key, {
      count: count + 1,
      lastMs: d,
      durs,
      hasValue,
      value,
      level,
      message,
      lastIdx: this.clock,
    });
    this.dirtyNodes.add(key);

    const trail = this.trails.get(lane);
    if (!trail || trail[0] !== node) {
      const next = [node];
      if (trail) for (const n of trail) if (n !== node && next.length < TRAIL) next.push(n);
      this.trails.set(lane, next);
    }
    this.dirtyLanes.add(lane); // also a repeat: a decision may have taken another branch

    if (typeof e.seq === "number") {
      if (this.traceSeq && e.seq > this.traceSeq + 1) this.traceLost += e.seq - this.traceSeq - 1;
      this.traceSeq = e.seq;
      this.dirtyOrch = true;
    }
  }

  private bump(key: string): void {
    this.edges.set(key, (this.edges.get(key) ?? 0) + 1);
    this.dirtyEdges.add(key);
  }

  private applyCall(e: MonitorEvent): void {
    if (e.component) this.calledComponents.add(e.component);
    const row: CallRow = {
      key: "",
      time: e.time,
      component: e.component ?? "",
      feature: e.feature ?? "",
      args: e.args,
      ok: e.ok,
      value: e.value,
      hasValue: "value" in e,
      error: e.error ?? "",
      latencyMs: e.latency_ms,
      detail: e.detail ?? "",
    };
    if (e.id) {
      const key = `${row.component}\u0000${e.id}`;
      for (let i = this.calls.length - 1; i >= 0 && i >= this.calls.length - CALLS_KEPT; i--) {
        const old = this.calls[i];
        if (old.key === key) {
          // A reply (or a repeat) of a call already listed: replace it in place.
          this.calls[i] = { ...row, key, time: old.time, args: e.args ?? old.args };
          this.dirtyCalls = true;
          return;
        }
      }
      row.key = key;
    } else {
      row.key = `#${++this.callSerial}`;
    }
    // In time order: a call reported without a reply (time-out) keeps its request's time.
    let at = this.calls.length;
    while (at > 0 && this.calls[at - 1].time > row.time) at--;
    this.calls.splice(at, 0, row);
    if (this.calls.length > 2 * CALLS_KEPT) this.calls.splice(0, this.calls.length - CALLS_KEPT);
    this.dirtyCalls = true;
  }

  newestCalls(): CallRow[] {
    return this.calls.slice(-CALLS_KEPT).reverse();
  }

  snapshot(): Snapshot {
    this.gen += 1; // the histograms are the snapshot's now
    this.ownedCounters = 0;
    return {
      nodes: new Map(this.nodes),
      edges: new Map(this.edges),
      trails: new Map(this.trails),
      components: new Map(this.components),
      orch: this.orch,
      calls: this.calls.slice(-CALLS_KEPT),
      clock: this.clock,
      traceSeq: this.traceSeq,
      traceLost: this.traceLost,
      exitPayload: this.exitPayload,
    };
  }

  restore(s: Snapshot): void {
    this.nodes = new Map(s.nodes);
    this.edges = new Map(s.edges);
    this.trails = new Map(s.trails);
    this.components = new Map(s.components);
    this.orch = s.orch;
    this.calls = s.calls.slice();
    this.clock = s.clock;
    this.traceSeq = s.traceSeq;
    this.traceLost = s.traceLost;
    this.exitPayload = s.exitPayload;
    this.gen += 1; // the histograms are still the snapshot's
    this.ownedCounters = 0;
    this.markAllDirty();
  }

  markAllDirty(): void {
    this.allDirty = true;
    this.dirtyOrch = true;
    this.dirtyCalls = true;
  }

  /** Clear what the renderer has drawn (nodes it had no time for stay in dirtyNodes). */
  clearDirty(): void {
    this.dirtyEdges.clear();
    this.dirtyLanes.clear();
    this.dirtyComponents.clear();
    this.dirtyOrch = false;
    this.dirtyCalls = false;
    this.calledComponents.clear();
    this.allDirty = false;
  }
}
