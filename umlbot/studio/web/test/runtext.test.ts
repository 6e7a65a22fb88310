import assert from "node:assert/strict";
import { test } from "node:test";

import { runEndText, speedWords } from "../src/features/run/text";

test("the end of a run is said in plain words", () => {
  const base = { goal_reached: false, collisions: 0, sim_s: 5.62, distance_m: 0.98 };
  assert.equal(
    runEndText({ ...base, reason: "interrupted" }),
    "You stopped the run (5.6 s of simulated driving, 0.98 m driven, no collisions).",
  );
  assert.equal(
    runEndText({ ...base, reason: "goal", goal_reached: true, collisions: 1 }),
    "The car reached the goal (5.6 s of simulated driving, 0.98 m driven, hit a wall once).",
  );
  assert.equal(
    runEndText({ ...base, reason: "collision", collisions: 3 }),
    "The run stopped because the car hit a wall (5.6 s of simulated driving, 0.98 m driven, hit a wall 3 times).",
  );
  assert.match(runEndText({ ...base, reason: "timeout" }), /^Time is up: the car did not reach the goal in time/);
  assert.match(
    runEndText({ ...base, reason: "orchestrator failed", failure: "LeftActuator.enabled: no reply" }),
    /^The model stopped with a problem: LeftActuator.enabled: no reply; the motors were stopped/,
  );
  assert.equal(runEndText({ reason: "failed", failure: "no track 'x'" }), "The run could not start: no track 'x'.");
  for (const reason of [
    "interrupted",
    "goal",
    "collision",
    "timeout",
    "orchestrator failed",
    "orchestrator ended",
    "service failed",
  ]) {
    const text = runEndText({ ...base, reason });
    assert.doesNotMatch(text, /interrupted|orchestrator|sim_s|wall second/, text);
  }
});

test("a run's speed in words", () => {
  assert.equal(speedWords(2), "twice as fast as real time");
  assert.equal(speedWords(1), "real time");
  assert.equal(speedWords(0.5), "half as fast as real time");
  assert.equal(speedWords(10), "10 times as fast as real time");
});
