// A recorded run as a timeline: its events in time order, with snapshots of the view state so that
// a seek applies only the events since the snapshot before it. Pure (test/replay.test.ts).

import type { Snapshot, StudioState } from "../../model/state";
import type { MonitorEvent } from "../../model/types";

// A snapshot of the state every SNAP_EVERY events, further apart when the duration histograms it
// would keep (copied since the last one) exceed COUNTERS_PER_EVENT per event since then: the
// snapshots' histograms take at most ~64 bytes per event of the trace (less than the event
// itself), and a seek applies at most the events between two snapshots (~20 ms for the 22 000 of
// a trace spread evenly over 2 000 nodes).
export const SNAP_EVERY = 1000;
export const COUNTERS_PER_EVENT = 8;

export interface Timeline {
  events: MonitorEvent[];
  times: Float64Array;
  t0: number;
  /** seconds from the first event to the last */
  duration: number;
  snaps: Snapshot[];
  /** events applied before each snapshot (ascending) */
  snapPos: number[];
  /** events applied */
  pos: number;
  /** seconds since the first event */
  time: number;
}

/** The timeline of `events` (in any order; ties keep theirs). Takes its snapshots by applying every
 * event to `state`, and leaves `state` at the start. */
export function buildTimeline(events: MonitorEvent[], state: StudioState): Timeline {
  const sorted = events
    .map((e, i) => ({ e, i }))
    .sort((a, b) => a.e.time - b.e.time || a.i - b.i)
    .map((x) => x.e);
  const times = new Float64Array(sorted.length);
  sorted.forEach((e, i) => {
    times[i] = e.time;
  });
  const t0 = sorted.length ? sorted[0].time : 0;
  const snaps: Snapshot[] = [];
  const snapPos: number[] = [];
  let since = 0;
  for (let i = 0; i < sorted.length; i++) {
    if (i === 0 || (since >= SNAP_EVERY && COUNTERS_PER_EVENT * since >= state.ownedCounters)) {
      snaps.push(state.snapshot());
      snapPos.push(i);
      since = 0;
    }
    state.apply(sorted[i]);
    since += 1;
  }
  const duration = sorted.length ? sorted[sorted.length - 1].time - t0 : 0;
  state.restore(snaps[0] ?? state.snapshot());
  return { events: sorted, times, t0, duration, snaps, snapPos, pos: 0, time: 0 };
}

/** The number of values of ascending `a` that are <= v. */
export function upperBound(a: ArrayLike<number>, v: number): number {
  let lo = 0;
  let hi = a.length;
  while (lo < hi) {
    const mid = (lo + hi) >> 1;
    if (a[mid] <= v) lo = mid + 1;
    else hi = mid;
  }
  return lo;
}

/** Move `state` to `t` seconds after the first event (clamped to the timeline): from the last
 * snapshot before it when that is nearer than where it is. Returns the trace events applied. */
export function seek(tl: Timeline, state: StudioState, t: number): number {
  tl.time = Math.min(Math.max(t, 0), tl.duration);
  const target = upperBound(tl.times, tl.t0 + tl.time + 1e-9);
  const s = upperBound(tl.snapPos, target) - 1; // the last snapshot at or before the target
  if (s >= 0 && (target < tl.pos || tl.snapPos[s] > tl.pos)) {
    state.restore(tl.snaps[s]);
    tl.pos = tl.snapPos[s];
  }
  let traces = 0;
  while (tl.pos < target) {
    const e = tl.events[tl.pos++];
    state.apply(e);
    if (e.type === "trace") traces += 1;
  }
  return traces;
}
