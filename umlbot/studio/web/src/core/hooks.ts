// `window.__studio`: what the page shows tests, benchmarks and the docs' screenshots (the browser
// tests wait on these; tests/test_studio_*browser.py, bench/studio.py, scripts/studio_doc_images.py).

import { layoutStats } from "../draw/layout-store";
import type { Op } from "../model/types";

export interface StudioHooks {
  /** per trace event drawn live: ms from the node's end to the frame that drew it (last 10 000) */
  latencies: number[];
  /** per trace event taken live: ms from the node's end to the studio's message that carried it, as
   * the page takes it (the part of `latencies` before the page's frame; last 10 000) */
  arrivals: number[];
  /** ms between frames while events flow (last 10 000) */
  frames: number[];
  /** the first diagram is drawn (or there is none to draw) */
  ready: boolean;
  /** trace events applied to the view state */
  applied: number;
  /** edit mode (null: the page only watches) */
  edit: EditHooks | null;
  /** the view follows the running robot (docs/studio.md, "Follow") */
  follow: boolean;
  /** pans follow made */
  followPans: number;
  /** hellos received: the first, and one per reconnection */
  hellos: number;
  /** counters the nodes' duration histograms hold (memory) */
  durationCounters: () => number;
  /** centre a node */
  reveal: (lane: string, node: string) => void;
  /** how clean diagram `id` is drawn: flow crossings and guard labels overlapped or struck */
  quality: (id: string) => { crossings: number; labels: number; flows: number } | null;
  /** how the lanes were laid out: by ELK, or taken from the layout cache (docs/studio.md) */
  layouts: typeof layoutStats;
  /** every collapsible region of diagram `id` open, or back to the opening view (features/regions) */
  regions: (id: string, how: "open" | "opening") => void;
}

export interface EditHooks {
  version: number;
  busy: boolean;
  dirty: boolean;
  requests: number;
  errors: string[];
  /** the version whose model the shown diagram draws (tests wait for it after an edit) */
  drawn: number;
  /** per answered edit (the last 200), performance.now() ms: when its request left the page, when
   * the answer came, when the frame that drew it with its diagnostics ended (bench/studio.py) */
  timings: EditTiming[];
  /** send operations as the page does (dev checks) */
  send?: (ops: Op[]) => Promise<boolean>;
}

export interface EditTiming {
  version: number;
  sent: number;
  answered: number;
  shown?: number;
}

declare global {
  interface Window {
    __studio: StudioHooks;
  }
}

/** The hooks, as `window.__studio`; the features fill in the functions. */
export function createHooks(): StudioHooks {
  const hooks: StudioHooks = {
    latencies: [],
    arrivals: [],
    frames: [],
    ready: false,
    applied: 0,
    edit: null,
    follow: false,
    followPans: 0,
    hellos: 0,
    durationCounters: () => 0,
    reveal: () => undefined,
    quality: () => null,
    layouts: layoutStats,
    regions: () => undefined,
  };
  window.__studio = hooks;
  return hooks;
}

const KEEP = 10_000;
/** Append `v` to a series of the hooks, keeping its last KEEP values. */
export function pushCapped(a: number[], v: number): void {
  a.push(v);
  if (a.length > KEEP) a.splice(0, a.length - KEEP);
}
