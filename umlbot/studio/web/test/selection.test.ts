import assert from "node:assert/strict";
import { test } from "node:test";
import { findLane, renamedSelection, selectedLane, validSelection } from "../src/core/selection";
import { lossText } from "../src/features/selection/loss";
import type { ModelView } from "../src/model/types";
import { twoDiagrams } from "./fixtures";

test("a selection follows what an edit renamed (and an undo's renaming back)", () => {
  const node = { type: "node" as const, lane: "A", id: "a" };
  assert.deepEqual(renamedSelection(node, [{ kind: "node", lane: "A", old: "a", new: "b" }]), { ...node, id: "b" });
  // the same id in another lane is another node
  assert.deepEqual(renamedSelection(node, [{ kind: "node", lane: "B", old: "a", new: "b" }]), node);
  const edge = { type: "edge" as const, lane: "A", source: "start", target: "a" };
  assert.deepEqual(renamedSelection(edge, [{ kind: "node", lane: "A", old: "a", new: "x" }]), { ...edge, target: "x" });
  assert.deepEqual(renamedSelection(edge, [{ kind: "lane", old: "A", new: "Z" }]), { ...edge, lane: "Z" });
  // a component's lane is named after it
  assert.deepEqual(renamedSelection({ type: "lane", lane: "Motor" }, [{ kind: "component", old: "Motor", new: "M" }]), {
    type: "lane",
    lane: "M",
  });
  assert.deepEqual(
    renamedSelection({ type: "component", name: "Motor" }, [{ kind: "component", old: "Motor", new: "M" }]),
    {
      type: "component",
      name: "M",
    },
  );
  // one after the other
  assert.deepEqual(
    renamedSelection(node, [
      { kind: "node", lane: "A", old: "a", new: "b" },
      { kind: "lane", old: "A", new: "Z" },
    ]),
    { type: "node", lane: "Z", id: "b" },
  );
  assert.equal(renamedSelection(null, [{ kind: "lane", old: "A", new: "Z" }]), null);
});

test("a selection whose thing is gone from the model is dropped", () => {
  assert.deepEqual(validSelection({ type: "node", lane: "A", id: "a" }, twoDiagrams), {
    type: "node",
    lane: "A",
    id: "a",
  });
  assert.equal(validSelection({ type: "node", lane: "A", id: "gone" }, twoDiagrams), null);
  assert.equal(validSelection({ type: "lane", lane: "gone" }, twoDiagrams), null);
  assert.equal(validSelection({ type: "edge", lane: "A", source: "a", target: "start" }, twoDiagrams), null);
  assert.equal(validSelection({ type: "component", name: "gone" }, twoDiagrams), null);
  // kept while there is no model to check it against; a part picked in the library stays
  assert.deepEqual(validSelection({ type: "lane", lane: "gone" }, null), { type: "lane", lane: "gone" });
  assert.deepEqual(validSelection({ type: "new-component", impl: "x" }, twoDiagrams), {
    type: "new-component",
    impl: "x",
  });
});

test("a node kind clicked in the palette goes to the selection's lane, else the diagram's only lane", () => {
  assert.equal(
    selectedLane({ type: "edge", lane: "B", source: "a", target: "end" }, twoDiagrams, "activity-main"),
    "B",
  );
  assert.equal(selectedLane(null, twoDiagrams, "activity-main"), null); // two lanes: which one?
  assert.equal(selectedLane(null, twoDiagrams, "activity-other"), "C");
  assert.equal(selectedLane({ type: "component", name: "M" }, twoDiagrams, "components"), null);
  assert.equal(findLane(twoDiagrams, "C")?.file, "activities/other.yaml");
});

test("deleting a lane with nodes or a component in use asks first, saying what goes with it", () => {
  const m: ModelView = {
    ...twoDiagrams,
    components: [
      { name: "Motor", kind: "motor", impl: "l298n", service: "motor", driver: "mock", features: [], ports: {} },
    ],
    diagrams: [
      {
        ...twoDiagrams.diagrams[0],
        lanes: [
          {
            ...twoDiagrams.diagrams[0].lanes[0],
            name: "Motor",
            component: "Motor",
            nodes: [
              { id: "start", kind: "start", label: "start", line: 2 },
              { id: "go", kind: "action", label: "Motor.forward(50)", line: 3, fields: { call: "Motor.forward(50)" } },
              { id: "end", kind: "end", label: "end", line: 4 },
            ],
          },
        ],
      },
      twoDiagrams.diagrams[1],
    ],
  };
  assert.equal(
    lossText({ type: "lane", lane: "Motor" }, m),
    "Delete the swimlane Motor with its 3 nodes and its file activities/main.yaml?",
  );
  assert.equal(lossText({ type: "lane", lane: "C" }, m), null); // only start and end
  assert.equal(
    lossText({ type: "component", name: "Motor" }, m),
    "Delete the component Motor? 1 swimlane runs on it and 1 node calls it (they will no longer check).",
  );
  assert.equal(lossText({ type: "component", name: "Sonar" }, m), null);
  assert.equal(lossText({ type: "node", lane: "Motor", id: "go" }, m), null);
});
