// What the user selected in edit mode (the properties panel shows it), and how a selection follows
// the model: renamed along with its thing, dropped when its thing is gone. Pure
// (test/selection.test.ts).

import type { ModelLane, ModelView, Renamed } from "../model/types";

export type Selection =
  | { type: "node"; lane: string; id: string }
  | { type: "edge"; lane: string; source: string; target: string }
  | { type: "component"; name: string }
  | { type: "lane"; lane: string }
  | { type: "new-component"; impl: string }
  | null;

/** The lane named `name` of model `m`. */
export function findLane(m: ModelView | null, name: string): ModelLane | undefined {
  for (const d of m?.diagrams ?? []) for (const l of d.lanes) if (l.name === name) return l;
  return undefined;
}

/** The selection after an edit, undo or redo renamed things: it keeps the renamed thing (a
 * rename's undo selects the node under its old id again, so the panel shows that id). */
export function renamedSelection(sel: Selection, renamed: Renamed[]): Selection {
  let s = sel;
  for (const r of renamed) {
    if (!s) return s;
    if (r.kind === "node") {
      if (s.type === "node" && s.lane === r.lane && s.id === r.old) s = { ...s, id: r.new };
      else if (s.type === "edge" && s.lane === r.lane) {
        s = {
          ...s,
          source: s.source === r.old ? r.new : s.source,
          target: s.target === r.old ? r.new : s.target,
        };
      }
    } else if (r.kind === "lane" && (s.type === "node" || s.type === "edge" || s.type === "lane") && s.lane === r.old) {
      s = { ...s, lane: r.new };
    } else if (r.kind === "component") {
      if (s.type === "component" && s.name === r.old) s = { ...s, name: r.new };
      else if ((s.type === "node" || s.type === "edge" || s.type === "lane") && s.lane === r.old) {
        s = { ...s, lane: r.new };
      }
    }
  }
  return s;
}

/** The selection if its thing is still in model `m` (kept as it is while there is no model). */
export function validSelection(s: Selection, m: ModelView | null): Selection {
  if (!s || !m) return s;
  if (s.type === "node" || s.type === "edge" || s.type === "lane") {
    const l = findLane(m, s.lane);
    if (!l) return null;
    if (s.type === "node" && !l.nodes.some((n) => n.id === s.id)) return null;
    if (s.type === "edge" && !l.edges.some((e) => e.source === s.source && e.target === s.target)) return null;
  } else if (s.type === "component" && !m.components.some((c) => c.name === s.name)) return null;
  return s;
}

/** The lane a node kind clicked in the palette goes to: the selection's, else the shown diagram's
 * only lane. */
export function selectedLane(s: Selection, m: ModelView | null, current: string): string | null {
  if (s && (s.type === "node" || s.type === "lane" || s.type === "edge")) return s.lane;
  const d = m?.diagrams.find((x) => x.id === current);
  return d && d.lanes.length === 1 ? d.lanes[0].name : null;
}
