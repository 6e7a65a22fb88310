import assert from "node:assert/strict";
import { test } from "node:test";
import { fleetRows, hubLine } from "../src/features/fleet/rows";

const hub = { url: "mqtt://hub:1883", connected: true };

test("a robot's row says its state, the node of each lane, its faults and how many parts are online", () => {
  const [row] = fleetRows({
    hub,
    followed: null,
    robots: [
      {
        robot: "car1",
        orchestrator: "running",
        reason: null,
        nodes: { Glance: "look_left", Stop: "both" },
        components: { LeftActuator: "online", Sensor: "offline" },
        faults: ["Sensor offline"],
        age_s: 0.2,
      },
    ],
  });
  assert.deepEqual(row, {
    robot: "car1",
    state: "running",
    running: "Glance: look_left, Stop: both",
    faults: "Sensor offline",
    components: "1/2 online",
    healthy: false,
  });
});

test("a failed run shows its reason; a robot with nothing seen yet says so", () => {
  const [row] = fleetRows({
    hub,
    followed: null,
    robots: [
      {
        robot: "b",
        orchestrator: "failed",
        reason: "Motor timed out",
        nodes: {},
        components: {},
        faults: [],
        age_s: 1,
      },
    ],
  });
  assert.equal(row.state, "failed (Motor timed out)");
  assert.equal(row.running, "–");
  assert.equal(row.components, "none seen");
  assert.equal(row.healthy, false);
});

test("the hub line says how many robots, or that the hub is unreachable and when it tries again", () => {
  assert.equal(hubLine(hub, 1), "hub mqtt://hub:1883: 1 robot");
  assert.equal(
    hubLine({ url: "mqtt://hub:1883", connected: false, problem: "Connection refused", retry_in_s: 1.2 }, 3),
    "hub mqtt://hub:1883 unreachable: Connection refused, next attempt in 2 s (showing what was last seen)",
  );
});
