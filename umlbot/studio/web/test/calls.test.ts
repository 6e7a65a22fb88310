import assert from "node:assert/strict";
import { test } from "node:test";
import { needsRebuild } from "../src/features/calls/order";

test("new calls go on top; one listed below a row shown already rebuilds the table", () => {
  const shown = new Set(["b", "c"]);
  assert.equal(needsRebuild(["a", "b", "c"], shown), false); // a: new, on top
  assert.equal(needsRebuild(["b", "c"], shown), false);
  assert.equal(needsRebuild(["a", "x", "b"], shown), false); // two new on top
  assert.equal(needsRebuild(["b", "x", "c"], shown), true); // x below b (a time-out keeps its time)
  assert.equal(needsRebuild([], shown), false);
});
