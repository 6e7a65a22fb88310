import assert from "node:assert/strict";
import { test } from "node:test";
import { brokerView, clockNote, gapsText, orchestratorText } from "../src/features/status/text";

test("the orchestrator pill says its state, detail and exit payload", () => {
  assert.equal(orchestratorText({ state: "running", detail: "" }, undefined), "orchestrator: running");
  assert.equal(
    orchestratorText({ state: "stopped", detail: "done" }, { code: 0 }),
    'orchestrator: stopped — done · exit {"code":0}',
  );
});

test("what was lost on the way, in words", () => {
  assert.equal(gapsText({ gaps: 0, lostFrames: 0, dropped: 0, lostTrace: 0 }), "");
  assert.equal(gapsText({ gaps: 1, lostFrames: 1, dropped: 0, lostTrace: 0 }), "⚠ 1 gap in the stream (1 frame lost)");
  assert.equal(
    gapsText({ gaps: 2, lostFrames: 5, dropped: 30, lostTrace: 7 }),
    "⚠ 2 gaps in the stream (5 frames lost) · 30 events dropped by the server · 7 trace events lost",
  );
});

test("the broker pill says whose broker, and when it is tried again", () => {
  const url = "mqtt://127.0.0.1:1883";
  const up = brokerView({ type: "broker", time: 0, url, connected: true }, false, 0, 0);
  assert.deepEqual(up, { state: "connected", text: "broker connected", title: `connected to ${url}` });
  assert.equal(brokerView({ type: "broker", time: 0, url, connected: true }, true, 0, 0).text, "sim broker connected");
  const down = brokerView(
    { type: "broker", time: 0, url, connected: false, problem: "refused", attempts: 3 },
    false,
    5000,
    2100,
  );
  assert.deepEqual(down, {
    state: "failed",
    text: `broker ${url}: refused, retrying in 3 s (attempt 3)`,
    title: `broker ${url}: refused, retrying in 3 s (attempt 3)`,
  });
  assert.equal(
    brokerView({ type: "broker", time: 0, url, connected: false, problem: "refused" }, false, 1000, 2000).text,
    `broker ${url}: refused, retrying…`,
  );
  assert.equal(brokerView({ type: "broker", time: 0, url, connected: false }, false, 0, 0).state, "connecting");
});

test("a simulated run's broker that closed with the run is said to have ended, not to be lost", () => {
  const url = "mqtt://127.0.0.1:40000";
  const ended = brokerView(
    {
      type: "broker",
      time: 0,
      url,
      connected: false,
      problem: null,
      ended: "the run has ended: the simulator and its broker are closed",
    },
    false,
    0,
    0,
  );
  assert.equal(ended.state, "ended");
  assert.equal(ended.text, "broker: the run has ended");
  assert.ok(!ended.text.includes("retrying"));
});

test("the figures say which clock they are in: simulated time on the nodes in the sim, wall clock for calls", () => {
  const sim = clockNote("live", true);
  assert.match(sim.text, /simulated time/);
  assert.match(sim.text, /calls: wall clock/);
  assert.match(sim.title, /0 ms/); // why a node that only calls shows 0 ms
  assert.match(clockNote("live", false).text, /robot's clock/);
  assert.match(clockNote("replay", true).text, /recorded run/);
});
