// The frame loop: one animation frame at a time, while anything is left to do. A frame applies
// what came ("frame.apply": live events, the replay's clock), draws the view state's changes within
// a time budget ("frame.render" after the drawing: the panels), then what follows a drawing
// ("frame.drawn": edit timings, follow, sim, latencies); it asks for the next frame while events
// flow or a feature is busy ("frame.flowing", "frame.busy"). When frames run late and the drawing
// is what costs (at least COSTLY_DRAW_MS), every other frame skips its drawing.

import type { Renderer } from "../draw/render";
import type { Bus } from "./events";
import { pushCapped, type StudioHooks } from "./hooks";
import type { Store } from "./store";

const RENDER_BUDGET_MS = 8; // node updates, per frame
const LATE_FRAME_MS = 24;
/** A drawing that took at least this long is what makes frames late: a late frame skips the next. */
export const COSTLY_DRAW_MS = 4;

export class Frames {
  private rafId = 0;
  private lastTs = 0;
  private skippedDraw = false;
  /** ms the last drawing took (its nodes and panels). */
  private lastDrawMs = 0;

  constructor(
    private bus: Bus,
    private store: Store,
    private hooks: StudioHooks,
    private renderer: Renderer,
    private now: () => number = () => performance.now(),
  ) {}

  /** Ask for a frame (one at a time). */
  schedule(): void {
    if (!this.rafId) this.rafId = requestAnimationFrame((ts) => this.tick(ts));
  }

  /** Draw the view state's changes now (nodes within `budgetMs`, 0: all), then the panels. */
  render(budgetMs = 0): void {
    const live = this.store.live;
    const full = live.allDirty;
    this.renderer.flush(live, budgetMs);
    this.bus.emit("frame.render", full);
    live.clearDirty();
  }

  private tick(ts: number): void {
    this.rafId = 0;
    const flowing = this.bus.request("frame.flowing") === true;
    const frameMs = this.lastTs ? ts - this.lastTs : 0;
    if (flowing && this.lastTs) pushCapped(this.hooks.frames, frameMs);
    this.lastTs = ts;

    this.bus.emit("frame.apply", ts);

    // When frames run late because the drawing is costly (many nodes changing), draw every other
    // frame only: events are still applied, the drawing catches up on the next frame. A cheap
    // drawing (a few nodes) is not what makes them late (a busy machine is): skipping it would only
    // show the nodes a frame later.
    const costly = this.lastDrawMs >= COSTLY_DRAW_MS;
    if (frameMs > LATE_FRAME_MS && costly && !this.skippedDraw && !this.store.live.allDirty) {
      this.skippedDraw = true;
    } else {
      this.skippedDraw = false;
      const t0 = this.now();
      this.render(RENDER_BUDGET_MS);
      this.lastDrawMs = this.now() - t0;
      this.bus.emit("frame.drawn");
    }

    if (flowing || this.skippedDraw || this.store.live.dirtyNodes.size > 0 || this.bus.request("frame.busy") === true)
      this.schedule();
    else this.lastTs = 0;
  }
}
