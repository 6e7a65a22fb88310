// Live: the monitor events the studio streams are queued as they come and applied to the view
// state in the frame loop, within a time budget per frame (a burst is spread over frames, the page
// stays responsive). A new session, run or robot starts the counts again. `window.__studio`:
// `applied`, `latencies` (a node's end to the frame that drew it), `arrivals` (a node's end to the
// message that carried it), `durationCounters`.

import { pushCapped } from "../../core/hooks";
import type { Studio } from "../../core/studio";
import { ModelIndex, StudioState } from "../../model/state";
import type { MonitorEvent } from "../../model/types";

const BUDGET_MS = 8; // applying queued events, per frame
const FLOWING_MS = 1000; // events came this recently: frames go on

export function install({ bus, store, hooks, frames }: Studio): void {
  const queue: MonitorEvent[] = [];
  let qpos = 0;
  let lastArrival = 0;
  // node end times (unix s) of the trace events applied but not drawn yet: each one's latency
  // (node end -> drawn) is recorded when the frame that shows it is drawn
  const unshownEnds: number[] = [];

  const clear = (): void => {
    queue.length = 0;
    qpos = 0;
  };

  const apply = (): void => {
    if (store.mode !== "live" || qpos >= queue.length) return;
    const state = store.live;
    const t0 = performance.now();
    let ran = false;
    while (qpos < queue.length) {
      const e = queue[qpos++];
      state.apply(e);
      if (e.type === "trace") {
        hooks.applied += 1;
        unshownEnds.push(e.time);
        ran = true;
      }
      if ((qpos & 255) === 0 && performance.now() - t0 > BUDGET_MS) break;
    }
    if (qpos >= queue.length) clear();
    if (ran) bus.emit("follow.due");
  };

  hooks.durationCounters = () => {
    let n = 0;
    for (const s of store.live.nodes.values()) n += s.durs.buckets;
    return n;
  };
  bus.on("session.reset", (_hello, shown) => {
    clear();
    store.index = new ModelIndex(shown);
    store.live = new StudioState(store.index);
  });
  bus.on("live.reset", () => {
    clear();
    store.live = new StudioState(store.index);
    store.live.markAllDirty();
    frames.schedule();
  });
  bus.on("server.run", (msg) => {
    if (msg.state === "running") bus.emit("live.reset"); // a new run: the counts start from zero
  });
  bus.on("server.events", (msg) => {
    if (store.mode === "live") {
      const now = Date.now();
      for (const e of msg.events) {
        if (e.type === "broker") continue;
        queue.push(e);
        if (e.type === "trace") pushCapped(hooks.arrivals, now - e.time * 1000);
      }
      lastArrival = performance.now();
    }
    store.live.dirtyOrch = true;
    frames.schedule();
  });
  bus.on("frame.flowing", () => (performance.now() - lastArrival < FLOWING_MS ? true : undefined));
  bus.on("frame.apply", apply);
  bus.on("frame.busy", () => (qpos < queue.length ? true : undefined));
  bus.on("frame.drawn", () => {
    if (!unshownEnds.length) return;
    const now = Date.now();
    for (const end of unshownEnds) pushCapped(hooks.latencies, now - end * 1000);
    unshownEnds.length = 0;
  });
}
