import assert from "node:assert/strict";
import { test } from "node:test";
import { buildTimeline, SNAP_EVERY, seek, upperBound } from "../src/features/replay/timeline";
import { ModelIndex, nodeKey, StudioState } from "../src/model/state";
import type { MonitorEvent } from "../src/model/types";
import { trace, twoDiagrams } from "./fixtures";

/** 2 500 runs of A's action, 10 ms apart, given out of order. */
function recording(): MonitorEvent[] {
  const events: MonitorEvent[] = [];
  for (let i = 0; i < 2500; i++) events.push(trace("A", "a", "action", 100 + i / 100, 1 + (i % 7)));
  return events.reverse();
}

const count = (s: StudioState): number => s.nodes.get(nodeKey("A", "a"))?.count ?? 0;

test("upperBound: how many values of an ascending list are at most v", () => {
  const a = [1, 2, 2, 3];
  assert.deepEqual(
    [0, 1, 2, 2.5, 3, 9].map((v) => upperBound(a, v)),
    [0, 1, 3, 3, 4, 4],
  );
  assert.equal(upperBound(new Float64Array(0), 1), 0);
});

test("a timeline sorts its events by time (ties keep their order) and starts at the beginning", () => {
  const state = new StudioState(new ModelIndex(twoDiagrams));
  const tied = [trace("A", "start", "start", 5), trace("B", "start", "start", 5), trace("A", "a", "action", 1)];
  const tl = buildTimeline(tied, state);
  assert.deepEqual(
    tl.events.map((e) => `${e.lane}/${e.node}`),
    ["A/a", "A/start", "B/start"],
  );
  assert.equal(tl.duration, 4);
  assert.equal(tl.pos, 0);
  assert.equal(state.nodes.size, 0); // back at the start
});

test("a seek forwards or backwards shows what applying the events up to then shows", () => {
  const state = new StudioState(new ModelIndex(twoDiagrams));
  const tl = buildTimeline(recording(), state);
  assert.equal(tl.snaps.length, Math.ceil(2500 / SNAP_EVERY)); // one every SNAP_EVERY events
  // 100.00 … 110.00: from the snapshot taken after 1 000 events, one event applied
  assert.equal(seek(tl, state, 10), 1);
  assert.equal(count(state), 1001);
  const p50 = state.nodes.get(nodeKey("A", "a"))?.durs.percentile(0.5);
  assert.equal(seek(tl, state, 24.99), 500); // from the snapshot after 2 000

  assert.equal(count(state), 2500);
  // back: from the snapshot before the moment, the same as the first time
  seek(tl, state, 10);
  assert.equal(count(state), 1001);
  assert.equal(state.nodes.get(nodeKey("A", "a"))?.durs.percentile(0.5), p50);
  // clamped to the recording
  seek(tl, state, -5);
  assert.equal(tl.time, 0);
  assert.equal(count(state), 1);
  seek(tl, state, 1e9);
  assert.equal(tl.time, tl.duration);
  assert.equal(count(state), 2500);
});
