import assert from "node:assert/strict";
import { test } from "node:test";
import { centredOn, FOLLOW_PAN_MS, inView, isFar, lastRan, markerSpot, panAt } from "../src/features/follow/decide";
import { ModelIndex, StudioState } from "../src/model/state";
import { trace, twoDiagrams } from "./fixtures";

test("the node that ran last is the latest of the diagram's lanes' current nodes", () => {
  const state = new StudioState(new ModelIndex(twoDiagrams));
  assert.equal(lastRan(twoDiagrams, "activity-main", state), null);
  state.apply(trace("A", "start", "start", 1));
  state.apply(trace("B", "start", "start", 2));
  state.apply(trace("A", "a", "action", 3));
  assert.equal(lastRan(twoDiagrams, "activity-main", state), "A\u0000a");
  state.apply(trace("B", "a", "action", 4));
  assert.equal(lastRan(twoDiagrams, "activity-main", state), "B\u0000a");
  // another diagram's lanes do not count
  state.apply(trace("C", "start", "start", 5));
  assert.equal(lastRan(twoDiagrams, "activity-main", state), "B\u0000a");
  assert.equal(lastRan(twoDiagrams, "activity-other", state), "C\u0000start");
});

test("a node is in view with the margin to spare; out of it, the view centres it", () => {
  const size = { W: 1000, H: 600 };
  const box = { x: 100, y: 100, w: 80, h: 40 };
  assert.ok(inView({ x: 0, y: 0, k: 1 }, box, size));
  assert.ok(!inView({ x: -80, y: 0, k: 1 }, box, size)); // 20 px from the left edge
  assert.ok(!inView({ x: 0, y: 0, k: 1 }, { ...box, x: 950 }, size));
  const to = centredOn(box, 2, size);
  assert.equal(to.x + (box.x + box.w / 2) * 2, 500);
  assert.equal(to.y + (box.y + box.h / 2) * 2, 300);
  assert.ok(!isFar({ x: 0, y: 0 }, { x: 700, y: 0 }, size));
  assert.ok(isFar({ x: 0, y: 0 }, { x: 800, y: 0 }, size));
});

test("a short pan is eased from where the view was to the node, and ends there", () => {
  const p = { x0: 0, y0: 100, x1: 200, y1: 0, t0: 1000 };
  assert.deepEqual(panAt(p, 1000), { x: 0, y: 100, done: false });
  const mid = panAt(p, 1000 + FOLLOW_PAN_MS / 2);
  assert.deepEqual(mid, { x: 100, y: 50, done: false });
  assert.ok(panAt(p, 1000 + FOLLOW_PAN_MS / 10).x < 20); // eased: slow at the start
  assert.deepEqual(panAt(p, 1000 + FOLLOW_PAN_MS), { x: 200, y: 0, done: true });
  assert.deepEqual(panAt(p, 99_999), { x: 200, y: 0, done: true });
});

test("the marker of a node off the canvas sits on the edge towards it and points at it", () => {
  const size = { W: 800, H: 600 };
  const below = markerSpot({ x: 0, y: 0, k: 1 }, { x: 100, y: 2000, w: 100, h: 40 }, size);
  assert.deepEqual(below, { left: 150, top: 576, arrow: "↓" });
  const left = markerSpot({ x: 0, y: 0, k: 1 }, { x: -500, y: 200, w: 100, h: 40 }, size);
  assert.equal(left.arrow, "←");
  assert.equal(left.left, 24);
});
