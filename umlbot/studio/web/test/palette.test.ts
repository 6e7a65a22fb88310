import assert from "node:assert/strict";
import { test } from "node:test";
import { wiredIn } from "../src/features/palette/wire";
import type { ModelLane } from "../src/model/types";

const lane = {
  name: "Stop",
  virtual: true,
  component: null,
  file: "activities/motion.yaml",
  line: 1,
  start: "start",
  datastores: [],
  nodes: [
    { id: "start", kind: "start", label: "", line: 2 },
    { id: "off", kind: "action", label: "Left.enabled(false)", line: 3 },
    { id: "which", kind: "decision", label: "which", line: 4 },
    { id: "end", kind: "end", label: "", line: 5 },
  ],
  edges: [
    { id: "start->off", source: "start", target: "off", label: "" },
    { id: "off->which", source: "off", target: "which", label: "" },
    { id: "which->end", source: "which", target: "end", label: "else" },
  ],
} as unknown as ModelLane;

test("a node dropped onto a flow goes between its two nodes", () => {
  assert.deepEqual(wiredIn(lane, "action", "action1", { source: "start", target: "off" }, null), [
    { op: "add_node", lane: "Stop", node: { id: "action1", kind: "action" } },
    { op: "connect", lane: "Stop", source: "action1", target: "off" },
    { op: "connect", lane: "Stop", source: "start", target: "action1" },
  ]);
  // out of a decision (a guarded way): only added; the guard's way is the user's to move
  assert.equal(wiredIn(lane, "action", "a", { source: "which", target: "end" }, null).length, 1);
});

test("a node added with a node selected goes after it, before what followed it", () => {
  const ops = wiredIn(lane, "datastore", "datastore1", null, "off");
  assert.deepEqual(
    ops.map((o) => [o.op, o.source, o.target]),
    [
      ["add_node", undefined, undefined],
      ["connect", "datastore1", "which"],
      ["connect", "off", "datastore1"],
    ],
  );
  // an end has no way out: it only takes the selected node's flow
  assert.deepEqual(
    wiredIn(lane, "end", "end2", null, "off").map((o) => o.op),
    ["add_node", "connect"],
  );
  // nothing selected: only added
  assert.equal(wiredIn(lane, "action", "a", null, null).length, 1);
});
