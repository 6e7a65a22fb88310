import assert from "node:assert/strict";
import { createHash } from "node:crypto";
import { test } from "node:test";
import type { ElkNode } from "elkjs/lib/elk-api.js";
import { keptPart, LAYOUT_FORMAT, layoutKey, sha256Hex } from "../src/draw/layout-store";

const nodeSha = (s: string): string => createHash("sha256").update(s, "utf8").digest("hex");

test("the key's SHA-256 is the standard one, at every padding length and for non-ASCII text", () => {
  for (const text of ["", "abc", "ü→✓ 𝄞", "x".repeat(55), "x".repeat(56), "x".repeat(64), "y".repeat(1000)])
    assert.equal(sha256Hex(text), nodeSha(text), `length ${text.length}`);
  assert.equal(sha256Hex("abc"), "ba7816bf8f01cfea414140de5dae2223b00361a396177a9cb410ff61f20015ad");
});

test("the key covers ELK's input and the format: any change of size or option is another key", () => {
  const graph: ElkNode = {
    id: "root",
    layoutOptions: { "elk.direction": "DOWN" },
    children: [{ id: "a", width: 10, height: 5 }],
  };
  const key = layoutKey(graph);
  assert.match(key, /^[0-9a-f]{64}$/);
  assert.equal(key, nodeSha(`${LAYOUT_FORMAT}\n${JSON.stringify(graph)}`));
  assert.match(LAYOUT_FORMAT, /elkjs \d+\.\d+/);
  assert.notEqual(layoutKey({ ...graph, children: [{ id: "a", width: 11, height: 5 }] }), key);
  assert.notEqual(layoutKey({ ...graph, layoutOptions: { "elk.direction": "RIGHT" } }), key);
});

test("what is kept is what the page draws from: places, sections, label boxes, size", () => {
  const out = {
    id: "root",
    width: 300,
    height: 200.5,
    children: [{ id: "a", x: 1.25, y: 2, width: 10, height: 5, labels: [{ id: "a#stats", x: 3, y: 4 }] }],
    edges: [
      {
        id: "f",
        sources: ["a"],
        targets: ["b"],
        sections: [{ id: "s", startPoint: { x: 1, y: 2 }, endPoint: { x: 3, y: 4 }, bendPoints: [{ x: 1, y: 4 }] }],
        labels: [{ id: "f#label", text: "else", x: 5, y: 6, width: 7, height: 8 }],
      },
      {
        id: "g",
        sources: ["a"],
        targets: ["a"],
        sections: [{ id: "t", startPoint: { x: 0, y: 0 }, endPoint: { x: 9, y: 9 } }],
      },
    ],
  } as unknown as ElkNode;
  assert.deepEqual(keptPart(out), {
    width: 300,
    height: 200.5,
    children: [{ id: "a", x: 1.25, y: 2 }],
    edges: [
      {
        id: "f",
        sections: [{ startPoint: { x: 1, y: 2 }, endPoint: { x: 3, y: 4 }, bendPoints: [{ x: 1, y: 4 }] }],
        labels: [{ x: 5, y: 6, width: 7, height: 8 }],
      },
      { id: "g", sections: [{ startPoint: { x: 0, y: 0 }, endPoint: { x: 9, y: 9 } }] },
    ],
  });
});
