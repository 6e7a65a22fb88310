import assert from "node:assert/strict";
import { test } from "node:test";
import { EventBus } from "../src/core/bus";
import type { Bus, StudioEvents } from "../src/core/events";
import { COSTLY_DRAW_MS, Frames } from "../src/core/frames";
import type { StudioHooks } from "../src/core/hooks";
import type { Store } from "../src/core/store";
import type { Renderer } from "../src/draw/render";

/** A frame loop driven by hand: `frame(ts)` runs the animation frame it asked for at `ts`; each
 * drawing takes `drawMs` of its clock. Returns the frames that drew (their `ts`). */
function loop(drawMs: number): { frame: (ts: number) => void; drawn: number[] } {
  const callbacks: FrameRequestCallback[] = [];
  (globalThis as { requestAnimationFrame?: unknown }).requestAnimationFrame = (cb: FrameRequestCallback) =>
    callbacks.push(cb);
  let clock = 0;
  const bus: Bus = new EventBus<StudioEvents>();
  const live = { allDirty: false, dirtyNodes: new Set<string>(), clearDirty: () => undefined };
  const store = { live } as unknown as Store;
  const hooks = { frames: [] } as unknown as StudioHooks;
  const renderer = { flush: () => (clock += drawMs) } as unknown as Renderer;
  const frames = new Frames(bus, store, hooks, renderer, () => clock);
  const drawn: number[] = [];
  let now = 0;
  bus.on("frame.drawn", () => drawn.push(now));
  bus.on("frame.flowing", () => true); // events flow: a frame asks for the next
  frames.schedule();
  return {
    frame: (ts) => {
      now = ts;
      const cb = callbacks.shift();
      assert.ok(cb, "a frame was asked for");
      cb(ts);
    },
    drawn,
  };
}

test("late frames still draw at once when the drawing is cheap (the nodes show without a frame's delay)", () => {
  const { frame, drawn } = loop(COSTLY_DRAW_MS / 4);
  for (const ts of [1000, 1040, 1080, 1120, 1160]) frame(ts); // every frame 40 ms after the last: late
  assert.deepEqual(drawn, [1000, 1040, 1080, 1120, 1160]);
});

test("late frames draw every other frame when the drawing is what costs", () => {
  const { frame, drawn } = loop(COSTLY_DRAW_MS * 2);
  for (const ts of [1000, 1040, 1080, 1120, 1160]) frame(ts);
  assert.deepEqual(drawn, [1000, 1080, 1160]);
});

test("frames on time draw every frame, however costly the drawing", () => {
  const { frame, drawn } = loop(COSTLY_DRAW_MS * 2);
  for (const ts of [1000, 1016.7, 1033.4, 1050.1]) frame(ts);
  assert.deepEqual(drawn, [1000, 1016.7, 1033.4, 1050.1]);
});
