// Which drawn node a compiler problem is about, and the marks the nodes get. Pure
// (test/diagnostics.test.ts).

import type { Mark } from "../../draw/render";
import { sameFile } from "../../model/paths";
import type { ModelIndex } from "../../model/state";
import type { Diagnostic, ModelView } from "../../model/types";

export interface NodeAt {
  diagram: string;
  lane: string;
  node: string;
}

/** The diagram of a node the server named (null when it is not drawn). */
export function nodeNamed(
  laneDiagram: Map<string, string>,
  index: ModelIndex,
  lane: string,
  node: string,
): NodeAt | null {
  const diagram = laneDiagram.get(lane);
  if (!diagram || !node) return null;
  return index.lanes.get(lane)?.nodes.has(node) ? { diagram, lane, node } : null;
}

/** The node a problem at file:line belongs to: the node of that file whose first line is the last
 * one at or before it (a bad guard on a branch's line marks its decision). */
export function nodeAtLine(model: ModelView | null, file: string, line: number): NodeAt | null {
  let best: (NodeAt & { line: number }) | null = null;
  for (const dg of model?.diagrams ?? []) {
    for (const lane of dg.lanes) {
      if (!sameFile(lane.file, file)) continue;
      for (const n of lane.nodes) {
        if (n.line <= line && (!best || n.line > best.line)) {
          best = { diagram: dg.id, lane: lane.name, node: n.id, line: n.line };
        }
      }
    }
  }
  return best;
}

/** A node's mark after problem `d` is added to `old` (an error wins over a warning; else the first). */
export function strongerMark(old: Mark | undefined, d: Diagnostic): Mark {
  if (!old || (old.level === "warning" && d.severity === "error")) return { level: d.severity, message: d.text };
  return old;
}

/** The nodes whose mark came, went or changed between `before` and `after` (only they are drawn again). */
export function changedMarks(before: Map<string, Mark>, after: Map<string, Mark>): string[] {
  const keys: string[] = [];
  for (const [key, mark] of after) {
    const old = before.get(key);
    if (!old || old.level !== mark.level || old.message !== mark.message) keys.push(key);
  }
  for (const key of before.keys()) if (!after.has(key)) keys.push(key);
  return keys;
}
