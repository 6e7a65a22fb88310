// How a new node is wired in when it is dropped onto a flow (it goes between the flow's two nodes)
// or added after the selected node (it goes after it, before what followed it). Pure
// (test/palette.test.ts).

import type { ModelLane, NodeKind, Op } from "../../model/types";

/** Node kinds with one outgoing flow (`next`): a flow out of them can be cut in two. */
const ONE_WAY = new Set(["start", "action", "datastore", "join", "send", "accept"]);

export interface Flow {
  source: string;
  target: string;
}

/** The operations that add node `id` of `kind` to `lane` and wire it in: between the two nodes of
 * `onFlow` (dropped onto it), else after `after` (the selected node of that lane), else none. */
export function wiredIn(lane: ModelLane, kind: NodeKind, id: string, onFlow: Flow | null, after: string | null): Op[] {
  const ops: Op[] = [{ op: "add_node", lane: lane.name, node: { id, kind } }];
  const kindOf = (n: string): string | undefined => lane.nodes.find((x) => x.id === n)?.kind;
  let source: string | null = null;
  let target: string | null = null;
  if (onFlow && ONE_WAY.has(kindOf(onFlow.source) ?? "")) {
    source = onFlow.source;
    target = onFlow.target;
  } else if (!onFlow && after && ONE_WAY.has(kindOf(after) ?? "")) {
    source = after;
    const out = lane.edges.filter((e) => e.source === after);
    target = out.length === 1 ? out[0].target : null;
  }
  if (source === null) return ops;
  if (target !== null && kind !== "end") ops.push({ op: "connect", lane: lane.name, source: id, target });
  ops.push({ op: "connect", lane: lane.name, source, target: id });
  return ops;
}
