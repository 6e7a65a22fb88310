import assert from "node:assert/strict";
import { test } from "node:test";
import { droppedAt } from "../src/features/connect/place";
import { newNodeId } from "../src/features/palette/names";
import { features, implsOf, paramText, signatureText } from "../src/model/library";
import type { ImplInfo, Library } from "../src/model/types";

const library = {
  kinds: {
    motor: {
      features: { forward: { params: [{ name: "speed", type: "number", minimum: 0, maximum: 100, unit: "%" }] } },
    },
  },
  implementations: [
    { id: "l298n", kind: "motor", features: ["forward", "brake"], aliases: [], settings_schema: null },
    {
      id: "hc_sr04",
      kind: "sonar",
      features: { read: { params: null, returns: "number" } },
      aliases: [],
      settings_schema: null,
    },
  ],
  builtins: [],
  node_kinds: {},
} as unknown as Library;

test("an implementation's features, with their parameters from its kind when it lists names only", () => {
  const [l298n, sonar] = library.implementations as ImplInfo[];
  assert.deepEqual(Object.keys(features(l298n, library)), ["forward", "brake"]);
  assert.equal(features(l298n, library).brake, null);
  assert.equal(signatureText("forward", features(l298n, library).forward!), "forward(speed: number 0..100 %)");
  assert.equal(signatureText("read", features(sonar, library).read!), "read → number");
  assert.deepEqual(
    implsOf(library, "sonar").map((i) => i.id),
    ["hc_sr04"],
  );
  assert.equal(paramText({ name: "cm", minimum: 2 }), "cm ≥ 2");
  assert.equal(paramText({ name: "deg", maximum: 180 }), "deg ≤ 180");
});

test("a new node's id: its kind and the first free number", () => {
  assert.equal(newNodeId("action", new Set(["start", "end"])), "action1");
  assert.equal(newNodeId("action", new Set(["action1", "action2"])), "action3");
});

test("a dragged element lands in whole diagram units, never before the origin", () => {
  assert.deepEqual(droppedAt(100, 50, 30, -20, 2), [115, 40]);
  assert.deepEqual(droppedAt(10, 10, -100, -100, 1), [0, 0]);
  assert.deepEqual(droppedAt(0.4, 0.6, 0, 0, 1), [0, 1]);
});
