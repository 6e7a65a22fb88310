import assert from "node:assert/strict";
import { test } from "node:test";
import { runEndText, speedWords, standStillText } from "../src/features/run/text";
import { safetyStop } from "../src/model/safety";

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

test("a run that ended with the car standing still says why: each safety stop in words", () => {
  const r = {
    reason: "timeout",
    sim_s: 30,
    stood_still: "LeftActuator: watchdog; RightActuator: watchdog",
    safety_stops: { RightActuator: "watchdog", LeftActuator: "orchestrator unresponsive" },
  };
  assert.equal(
    standStillText(r),
    "The car stood still because a safety stop stopped its motors: LeftActuator: the running model " +
      "stopped answering, so it stopped itself; RightActuator: no command came in time, so its watchdog stopped it.",
  );
  // the deadman of the simulated world is said by the run's own words
  assert.match(
    standStillText({ reason: "timeout", stood_still: "the left motor's driver stopped renewing it" }),
    /renewing/,
  );
  assert.equal(standStillText({ reason: "goal", goal_reached: true }), "");
});

test("a component's retained state says its safety stop", () => {
  assert.equal(safetyStop({ enabled: false, stop_reason: "watchdog" }), "watchdog");
  assert.equal(safetyStop({ enabled: true, stop_reason: null }), null);
  assert.equal(safetyStop([1, 2]), null);
  assert.equal(safetyStop(undefined), null);
});
