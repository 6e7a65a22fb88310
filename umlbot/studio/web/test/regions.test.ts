import assert from "node:assert/strict";
import { test } from "node:test";
import { collapseDiagram, collapseLane, laneRegions, REGION_KIND, regionMembers } from "../src/draw/regions";
import type { ModelEdge, ModelLane, ModelNode } from "../src/model/types";

const n = (id: string, kind = "action"): ModelNode => ({ id, kind, label: id, line: 1 });
const flows = (...pairs: [string, string, string?][]): ModelEdge[] =>
  pairs.map(([source, target, label], i) => ({ id: `e${i}`, source, target, label: label ?? "" }));

/** start -> d; d branches to a side way (`way`, with a decision of its own, 8 nodes) and to `main`;
 * both meet again at `merge`; plus filler so that 8 nodes are at most a quarter of the lane. */
function lane(sideDecision = true, extraEntry = false): ModelLane {
  const side = ["s0", "s1", "s2", "s3", "s4", "s5", "s6", "s7"];
  const nodes = [n("start", "start"), n("d", "decision"), ...side.map((s) => n(s)), n("main"), n("merge")];
  if (sideDecision) nodes[3] = n("s1", "decision");
  const edges: [string, string, string?][] = [
    ["start", "d"],
    ["d", "s0", "a > 1"],
    ["d", "s4", "a > 2"],
    ["d", "main", "else"],
    ["s0", "s1"],
    ["s1", "s2", "x"],
    ["s1", "s4", "else"],
    ["s2", "s3"],
    ["s3", "s5"],
    ["s4", "s5"],
    ["s5", "s6"],
    ["s6", "s7"],
    ["s7", "merge"],
    ["main", "merge"],
  ];
  if (extraEntry) edges.push(["main", "s3"]);
  // filler: a straight stretch after the merge (35 nodes: 8 are at most a quarter)
  let last = "merge";
  for (let i = 0; i < 22; i++) {
    nodes.push(n(`f${i}`));
    edges.push([last, `f${i}`]);
    last = `f${i}`;
  }
  nodes.push(n("end", "end"));
  edges.push([last, "end"]);
  return {
    name: "L",
    virtual: false,
    component: null,
    file: "",
    line: 1,
    start: "start",
    datastores: [],
    nodes,
    edges: flows(...edges),
  };
}

test("a branch up to where it meets the others again, entered only from its decision, is a region", () => {
  const rs = laneRegions(lane());
  assert.equal(rs.length, 1);
  assert.equal(rs[0].id, "region:s0");
  assert.deepEqual(rs[0].members, ["s0", "s1", "s2", "s3", "s4", "s5", "s6", "s7"]);
  // a straight stretch (no decision of its own) stays drawn; so does a branch entered from elsewhere
  assert.deepEqual(laneRegions(lane(false)), []);
  assert.deepEqual(laneRegions(lane(true, true)), []);
});

test("collapsed, a region is one box with its flows in and out; two flows in are one", () => {
  const l = lane();
  const c = collapseLane(l, laneRegions(l));
  const box = c.nodes.find((x) => x.kind === REGION_KIND)!;
  assert.equal(box.id, "region:s0");
  assert.equal(box.label, "8 steps: s0 …");
  assert.deepEqual(regionMembers(box), ["s0", "s1", "s2", "s3", "s4", "s5", "s6", "s7"]);
  assert.equal(c.nodes.length, l.nodes.length - 7);
  assert.ok(!c.nodes.some((x) => x.id === "s3"));
  const into = c.edges.filter((e) => e.target === box.id);
  assert.deepEqual(
    into.map((e) => [e.source, e.label]),
    [["d", "a > 1 or a > 2"]],
  );
  assert.deepEqual(
    c.edges.filter((e) => e.source === box.id).map((e) => e.target),
    ["merge"],
  );
  assert.ok(!c.edges.some((e) => e.source === "s1" || e.target === "s5"));
  // the model's lane is left alone
  assert.equal(l.nodes.length, 35);
  // opened: the diagram as it is
  const d = { id: "activity-x", title: "x", file: "", lanes: [l] };
  assert.equal(
    collapseDiagram(d, () => true),
    d,
  );
  assert.equal(collapseDiagram(d, () => false).lanes[0].nodes.length, 28);
});
