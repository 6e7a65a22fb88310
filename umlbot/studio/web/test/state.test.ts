// Unit tests of the page's view state (run: npm test). The browser tests in tests/ cover the page.
import assert from "node:assert/strict";
import { test } from "node:test";
import { percentiles } from "../src/model/durations";
import type { NodeStats } from "../src/model/state";
import { edgeKey, ModelIndex, nodeKey, StudioState } from "../src/model/state";
import type { ModelView, MonitorEvent } from "../src/model/types";

const model: ModelView = {
  version: 1,
  name: "t",
  signals: [],
  components: [],
  links: [],
  diagrams: [
    {
      id: "activity-main",
      title: "main",
      file: "main.yaml",
      lanes: [
        {
          name: "L",
          virtual: false,
          component: null,
          file: "main.yaml",
          line: 1,
          start: "start",
          datastores: ["x"],
          nodes: [
            { id: "start", kind: "start", label: "start", line: 2 },
            { id: "set", kind: "datastore", label: "x = 1", line: 3, store: "x" },
            { id: "d", kind: "decision", label: "d", line: 4 },
            { id: "a", kind: "action", label: "A", line: 5 },
            { id: "b", kind: "action", label: "B", line: 6 },
            { id: "m", kind: "action", label: "M", line: 7 },
            { id: "end", kind: "end", label: "end", line: 8 },
          ],
          edges: [
            { id: "1", source: "start", target: "set", label: "" },
            { id: "2", source: "set", target: "d", label: "" },
            { id: "3", source: "d", target: "a", label: "x > 0" },
            { id: "4", source: "d", target: "b", label: "else" },
            { id: "5", source: "a", target: "m", label: "" },
            { id: "6", source: "b", target: "m", label: "" },
            { id: "7", source: "m", target: "d", label: "" },
            { id: "8", source: "d", target: "end", label: "done" },
          ],
        },
      ],
    },
  ],
};

let clock = 1000;
const trace = (node: string, kind: string, ms: number, extra: Partial<MonitorEvent> = {}): MonitorEvent => {
  clock += 1;
  return {
    type: "trace",
    time: clock,
    lane: "L",
    node,
    kind,
    duration_ms: ms,
    level: "info",
    ...extra,
  };
};

test("counts, last duration, datastore value, branch counts, trail", () => {
  const s = new StudioState(new ModelIndex(model));
  for (const e of [
    trace("start", "start", 0),
    trace("set", "datastore", 1, { value: 7 }),
    trace("d", "decision", 0, { value: "a" }),
    trace("a", "action", 10),
    trace("m", "action", 2),
    trace("d", "decision", 0, { value: "b" }),
    trace("b", "action", 20),
    trace("m", "action", 4),
  ])
    s.apply(e);
  const m = s.nodes.get(nodeKey("L", "m"))!;
  assert.equal(m.count, 2);
  assert.equal(m.lastMs, 4);
  assert.equal(s.nodes.get(nodeKey("L", "set"))!.value, 7);
  assert.equal(s.edges.get(edgeKey("L", "d", "a")), 1);
  assert.equal(s.edges.get(edgeKey("L", "d", "b")), 1);
  assert.equal(s.edges.get(edgeKey("L", "a", "m")), 1); // m entered from a, then from b
  assert.equal(s.edges.get(edgeKey("L", "b", "m")), 1);
  assert.equal(s.edges.get(edgeKey("L", "m", "d")), 1);
  assert.equal(s.edges.get(edgeKey("L", "set", "d")), 1);
  assert.deepEqual(s.trails.get("L"), ["m", "b", "d", "a"]);
});

test("a node's colour follows its last run", () => {
  const s = new StudioState(new ModelIndex(model));
  s.apply(trace("a", "action", 1, { level: "error", error: "boom" }));
  assert.equal(s.nodes.get(nodeKey("L", "a"))!.level, "error");
  assert.equal(s.nodes.get(nodeKey("L", "a"))!.message, "boom");
  s.apply(trace("a", "action", 1));
  assert.equal(s.nodes.get(nodeKey("L", "a"))!.level, "info");
});

test("components, orchestrator, calls (a reply updates its call, newest first)", () => {
  const s = new StudioState(new ModelIndex(model));
  s.apply({ type: "availability", time: 1, component: "M", state: "online", impl: "l298n", driver: "mock" });
  s.apply({ type: "state", time: 2, component: "M", payload: { enabled: true } });
  s.apply({ type: "orchestrator", time: 3, state: "failed", detail: "M went offline" });
  s.apply({ type: "call", time: 4, component: "M", feature: "enabled", args: [true], id: "c1" });
  s.apply({
    type: "call",
    time: 5,
    component: "M",
    feature: "dutycycle",
    args: [50],
    id: "c2",
    ok: true,
    latency_ms: 3,
  });
  s.apply({
    type: "call",
    time: 6,
    component: "M",
    feature: "enabled",
    args: [true],
    id: "c1",
    ok: true,
    latency_ms: 2,
  });
  assert.deepEqual(s.components.get("M"), {
    avail: "online",
    impl: "l298n",
    driver: "mock",
    hasRetained: true,
    retained: { enabled: true },
  });
  assert.deepEqual(s.orch, { state: "failed", detail: "M went offline" });
  const calls = s.newestCalls();
  assert.deepEqual(
    calls.map((c) => [c.feature, c.ok]),
    [
      ["dutycycle", true],
      ["enabled", true],
    ],
  );
  assert.equal(calls[1].time, 4); // listed when it was sent
  s.apply({ type: "availability", time: 7, component: "M", state: "offline" });
  assert.equal(s.components.get("M")!.driver, ""); // nothing runs it now: no driver said
});

test("restoring a snapshot and re-applying gives the same state (replay scrubbing)", () => {
  const events: MonitorEvent[] = [];
  for (let i = 0; i < 300; i++) {
    events.push(trace("d", "decision", 0, { value: i % 3 ? "a" : "b" }));
    events.push(trace(i % 3 ? "a" : "b", "action", (i * 7) % 13));
    events.push(trace("m", "action", (i * 5) % 11));
  }
  const s = new StudioState(new ModelIndex(model));
  const snaps = [];
  for (let i = 0; i < events.length; i++) {
    if (i % 100 === 0) snaps.push(s.snapshot());
    s.apply(events[i]);
  }
  const end = JSON.stringify([...s.nodes].map(([k, v]) => [k, v.count, percentiles(v.durs)]));
  assert.notEqual(end, JSON.stringify([...snaps[4].nodes].map(([k, v]) => [k, v.count, percentiles(v.durs)])));
  // back to event 250, then forward again to the end
  const stats = (st: StudioState): string =>
    JSON.stringify([...st.nodes].map(([k, v]) => [k, v.count, percentiles(v.durs)]));
  s.restore(snaps[2]);
  for (let i = 200; i < 250; i++) s.apply(events[i]);
  assert.equal(s.nodes.get(nodeKey("L", "m"))!.count, 83); // 83 rounds of 3 events, then a decision
  // the snapshot's histograms were not changed by the events applied after it (copy on write)
  const fresh = new StudioState(new ModelIndex(model));
  for (let i = 0; i < 250; i++) fresh.apply(events[i]);
  assert.equal(stats(s), stats(fresh));
  s.restore(snaps[8]);
  for (let i = 800; i < events.length; i++) s.apply(events[i]);
  assert.equal(stats(s), end);
});

test("ownedCounters: the histogram counters the next snapshot would keep", () => {
  const s = new StudioState(new ModelIndex(model));
  const a = (): NodeStats => s.nodes.get(nodeKey("L", "a"))!;
  for (const ms of [10, 12]) s.apply(trace("a", "action", ms));
  s.apply(trace("b", "action", 5));
  assert.equal(
    s.ownedCounters,
    [...s.nodes.values()].reduce((n, v) => n + v.durs.buckets, 0),
  );
  const snap = s.snapshot();
  assert.equal(s.ownedCounters, 0);
  s.apply(trace("a", "action", 500)); // a's histogram is copied (and grows): b's stays shared
  assert.equal(s.ownedCounters, a().durs.buckets);
  assert.notEqual(a().durs, snap.nodes.get(nodeKey("L", "a"))!.durs);
  assert.equal(snap.nodes.get(nodeKey("L", "a"))!.durs.count, 2);
  assert.equal(snap.nodes.get(nodeKey("L", "a"))!.durs.max, 12);
  s.restore(snap);
  assert.equal(s.ownedCounters, 0);
});
