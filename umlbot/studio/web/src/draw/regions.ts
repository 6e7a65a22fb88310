// Collapsible regions of an activity lane (issue 28): a decision's branch whose nodes are reached
// only through that branch (one way in: the branch's first node dominates them all) can be drawn
// as one box, "17 steps: Measure …", with the region's flows in and out. Pure (test/regions.test.ts).
//
// The opening rule: a region is drawn collapsed when it holds at least REGION_MIN nodes and at
// most a quarter of its lane (a bigger branch is the lane's main way, not a detour), and is not
// inside another such region (the outermost is collapsed; what is inside shows once it is
// expanded). The car's `main`: the way into an opening beside the road (17 nodes) and the
// no-room-ahead look (8 nodes); its start-up chain and the step forward stay drawn.

import type { ModelDiagram, ModelEdge, ModelLane, ModelNode } from "../model/types";

export const REGION_MIN = 8;
/** a region holds at most a quarter of its lane, and at most this many nodes */
export const REGION_MAX = 60;
export const REGION_KIND = "region";
const PREFIX = "region:";

export interface Region {
  /** the box's node id: `region:<first node>` */
  id: string;
  lane: string;
  /** the branch's first node (the way in) */
  entry: string;
  /** every node of the region, the way in first, in the lane's order */
  members: string[];
}

export const isRegionId = (id: string): boolean => id.startsWith(PREFIX);

/** Each node's immediate dominator from `root` (every way from the root to it passes there), and
 * the nodes reached in reverse post-order. */
function dominators(
  root: string | undefined,
  succ: Map<string, string[]>,
): { idom: Map<string, string>; rpo: string[] } {
  const idom = new Map<string, string>();
  if (root === undefined) return { idom, rpo: [] };
  const start = { id: root };
  // reverse post-order from the start
  const post: string[] = [];
  const seen = new Set<string>([start.id]);
  const stack: [string, number][] = [[start.id, 0]];
  while (stack.length) {
    const top = stack[stack.length - 1];
    const out = succ.get(top[0]) ?? [];
    if (top[1] >= out.length) {
      post.push(top[0]);
      stack.pop();
      continue;
    }
    const w = out[top[1]++];
    if (!seen.has(w)) {
      seen.add(w);
      stack.push([w, 0]);
    }
  }
  const rpo = post.reverse();
  const order = new Map(rpo.map((v, i) => [v, i]));
  const pred = new Map<string, string[]>();
  for (const [v, out] of succ) for (const w of out) if (order.has(v)) pred.set(w, [...(pred.get(w) ?? []), v]);
  idom.set(start.id, start.id);
  const intersect = (a: string, b: string): string => {
    let x = a;
    let y = b;
    while (x !== y) {
      while ((order.get(x) ?? 0) > (order.get(y) ?? 0)) x = idom.get(x)!;
      while ((order.get(y) ?? 0) > (order.get(x) ?? 0)) y = idom.get(y)!;
    }
    return x;
  };
  // Cooper, Harvey and Kennedy's iteration
  for (let changed = true; changed; ) {
    changed = false;
    for (const v of rpo) {
      if (v === start.id) continue;
      let d: string | undefined;
      for (const p of pred.get(v) ?? []) if (idom.has(p)) d = d === undefined ? p : intersect(p, d);
      if (d !== undefined && idom.get(v) !== d) {
        idom.set(v, d);
        changed = true;
      }
    }
  }
  return { idom, rpo };
}

/** The regions of a lane drawn collapsed when it opens (the rule above), outermost first. */
export function laneRegions(lane: ModelLane): Region[] {
  const known = new Set(lane.nodes.map((n) => n.id));
  const succ = new Map<string, string[]>(lane.nodes.map((n) => [n.id, []]));
  const preds = new Map<string, Set<string>>(lane.nodes.map((n) => [n.id, new Set()]));
  const kind = new Map(lane.nodes.map((n) => [n.id, n.kind]));
  const max = Math.min(REGION_MAX, Math.floor(lane.nodes.length / 4));
  for (const e of lane.edges) {
    if (!known.has(e.source) || !known.has(e.target)) continue;
    succ.get(e.source)!.push(e.target);
    preds.get(e.target)!.add(e.source);
  }
  const first = lane.nodes.find((n) => n.id === lane.start) ?? lane.nodes.find((n) => n.kind === "start");
  const { idom, rpo } = dominators(first?.id, succ);
  // post-dominators: dominators of the flows turned round, from a virtual exit before every end
  const EXIT = "\u0000exit";
  const back = new Map<string, string[]>(lane.nodes.map((n) => [n.id, [...(preds.get(n.id) ?? [])]]));
  back.set(
    EXIT,
    lane.nodes.filter((n) => n.kind === "end" || !succ.get(n.id)?.length).map((n) => n.id),
  );
  const ipdom = dominators(EXIT, back).idom;
  /** the nodes a branch reaches before `stop`, a node every way on from it passes, when nothing
   * outside them but the decision `d` leads in */
  const before = (d: string, t: string, stop: string): Set<string> | null => {
    const out = new Set<string>([t]);
    const todo = [t];
    while (todo.length) {
      for (const w of succ.get(todo.pop()!) ?? []) {
        if (w === stop || out.has(w)) continue;
        if (w === d || kind.get(w) === "start" || out.size > max) return null;
        out.add(w);
        todo.push(w);
      }
    }
    for (const v of out) for (const u of preds.get(v) ?? []) if (u !== d && !out.has(u)) return null;
    return out;
  };
  /** a branch's hammock: the most nodes it reaches before the flows meet again (a post-dominator
   * of its first node), when nothing but the decision leads in */
  const hammock = (d: string, t: string): Set<string> | null => {
    let best: Set<string> | null = null;
    for (let stop = ipdom.get(t); stop !== undefined && stop !== EXIT; stop = ipdom.get(stop)) {
      const h = before(d, t, stop);
      if (h && h.size > max) break;
      if (h) best = h;
      if (stop === ipdom.get(stop)) break;
    }
    return best;
  };
  // the dominator tree: each node's children, and how many nodes each one dominates (a node's
  // immediate dominator comes before it in reverse post-order)
  const children = new Map<string, string[]>();
  const size = new Map<string, number>();
  for (let i = rpo.length - 1; i >= 0; i--) {
    const v = rpo[i];
    const d = idom.get(v);
    size.set(v, (size.get(v) ?? 0) + 1);
    if (d !== undefined && d !== v) {
      size.set(d, (size.get(d) ?? 0) + size.get(v)!);
      children.set(d, [...(children.get(d) ?? []), v]);
    }
  }
  const below = (t: string): Set<string> => {
    const out = new Set<string>();
    const todo = [t];
    while (todo.length) {
      const v = todo.pop()!;
      out.add(v);
      todo.push(...(children.get(v) ?? []));
    }
    return out;
  };
  const candidates: Set<string>[] = [];
  const entries: string[] = [];
  for (const n of lane.nodes) {
    if (n.kind !== "decision") continue;
    for (const t of new Set(succ.get(n.id))) {
      if (t === n.id || !idom.has(t) || kind.get(t) === "start") continue;
      const h = hammock(n.id, t);
      const k = size.get(t) ?? 0;
      const r =
        h && h.size >= REGION_MIN ? h : preds.get(t)!.size === 1 && k >= REGION_MIN && k <= max ? below(t) : null;
      // a straight stretch (no decision of its own) reads well as it is: it stays drawn
      if (r && [...r].some((v) => kind.get(v) === "decision")) {
        candidates.push(r);
        entries.push(t);
      }
    }
  }
  const picked: Region[] = [];
  const taken = new Set<string>();
  const byIndex = candidates.map((_, i) => i).sort((a, b) => candidates[b].size - candidates[a].size);
  for (const i of byIndex) {
    if ([...candidates[i]].some((v) => taken.has(v))) continue;
    for (const v of candidates[i]) taken.add(v);
    const entry = entries[i];
    const members = [entry, ...lane.nodes.map((x) => x.id).filter((v) => v !== entry && candidates[i].has(v))];
    picked.push({ id: `${PREFIX}${entry}`, lane: lane.name, entry, members });
  }
  return picked;
}

/** The text of a region's box. */
export function regionLabel(lane: ModelLane, r: Region): string {
  const entry = lane.nodes.find((n) => n.id === r.entry);
  return `${r.members.length} steps: ${entry?.label ?? r.entry} …`;
}

/** The lane as drawn with `regions` collapsed: each region one node, with its flows in and out
 * (flows inside it are not drawn; two flows between the same two nodes are drawn as one, their
 * guards joined by "or"). */
export function collapseLane(lane: ModelLane, regions: Region[]): ModelLane {
  if (!regions.length) return lane;
  const owner = new Map<string, Region>();
  for (const r of regions) for (const m of r.members) owner.set(m, r);
  const nodes: ModelNode[] = [];
  for (const n of lane.nodes) {
    const r = owner.get(n.id);
    if (!r) nodes.push(n);
    else if (r.entry === n.id)
      nodes.push({
        id: r.id,
        kind: REGION_KIND,
        label: regionLabel(lane, r),
        line: n.line,
        fields: { members: r.members },
      });
  }
  const edges: ModelEdge[] = [];
  const at = new Map<string, ModelEdge>();
  for (const e of lane.edges) {
    const source = owner.get(e.source)?.id ?? e.source;
    const target = owner.get(e.target)?.id ?? e.target;
    if (source === target && source !== e.source) continue; // inside a region
    const key = `${source}>${target}`;
    const was = at.get(key);
    if (was) {
      if (e.label && was.label !== e.label) was.label = was.label ? `${was.label} or ${e.label}` : e.label;
      continue;
    }
    const edge = { ...e, source, target };
    at.set(key, edge);
    edges.push(edge);
  }
  return { ...lane, nodes, edges };
}

/** A region's members, from its box's node (collapseLane puts them there). */
export function regionMembers(n: ModelNode): string[] {
  const m = n.fields?.members;
  return Array.isArray(m) ? (m as string[]) : [];
}

/** The diagram as drawn: every lane with its regions collapsed but those `expanded(lane, region)`
 * says are open. */
export function collapseDiagram(d: ModelDiagram, expanded: (lane: string, region: string) => boolean): ModelDiagram {
  let changed = false;
  const lanes = d.lanes.map((l) => {
    const shut = laneRegions(l).filter((r) => !expanded(l.name, r.id));
    if (!shut.length) return l;
    changed = true;
    return collapseLane(l, shut);
  });
  return changed ? { ...d, lanes } : d;
}
