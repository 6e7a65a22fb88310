import assert from "node:assert/strict";
import { test } from "node:test";
import {
  fitView,
  keptInView,
  laneHeadPlace,
  MAX_K,
  MIN_K,
  OPEN_K,
  panToShow,
  READABLE_K,
  WIDE_K,
  wheelZoom,
  zoomedAt,
} from "../src/core/geometry";

const canvas = { W: 1000, H: 600 };

test("a small diagram is fitted whole, centred, zoomed in at most 1.25 times", () => {
  const v = fitView(canvas, { width: 100, height: 50 }, true);
  assert.equal(v.k, 1.25);
  assert.equal(v.x, (1000 - 125) / 2);
  assert.equal(v.y, (600 - 62.5) / 2);
});

test("a diagram too big to read whole opens readable, from the top, around its start node", () => {
  const d = { width: 5000, height: 4000, focus: { x: 4000, y: 10 } };
  const v = fitView(canvas, d, true);
  assert.equal(v.k, OPEN_K);
  assert.equal(v.y, 16); // from the top
  // the start node is in the middle (not past the diagram's right edge)
  assert.ok(Math.abs(v.x + d.focus.x * v.k - canvas.W / 2) < 1e-9);
  // Fit (not `readable`): the whole of it, however small
  const whole = fitView(canvas, d, false);
  assert.ok(whole.k < READABLE_K);
  assert.ok(whole.k * d.width <= canvas.W && whole.k * d.height <= canvas.H);
});

test("a wide diagram that is readable at the canvas's width opens at that width", () => {
  const v = fitView(canvas, { width: 1200, height: 3000 }, true);
  assert.equal(v.k, (1000 - 32) / 1200);
  assert.equal(v.y, 16);
  // a tall one narrower than that, not readable whole: at its width when that is OPEN_K or more,
  // else at OPEN_K (cut at the sides, around its start) — never smaller than a wider one opens
  assert.equal(fitView(canvas, { width: 1400, height: 3000 }, true).k, OPEN_K);
  assert.ok((1000 - 32) / 1400 >= READABLE_K);
  // a short one (its height fits at its width) opens at its width down to READABLE_K
  assert.equal(fitView(canvas, { width: 1400, height: 700 }, true).k, (1000 - 32) / 1400);
});

test("a short diagram too wide to be read whole opens whole down to WIDE_K, not cut at its right edge", () => {
  // five lanes of 256 on a laptop's canvas (750 px): whole at 0.56
  const laptop = { W: 750, H: 650 };
  const v = fitView(laptop, { width: 1280, height: 400 }, true);
  assert.equal(v.k, (750 - 32) / 1280);
  assert.ok(v.k >= WIDE_K && v.k < READABLE_K);
  assert.ok(v.x >= 0 && v.x + 1280 * v.k <= laptop.W);
  // wider still: readable from the start node, as before
  assert.equal(fitView(laptop, { width: 2000, height: 400 }, true).k, OPEN_K);
  // a tall one whose height does not fit is not shrunk below READABLE_K for it
  assert.equal(fitView(laptop, { width: 1280, height: 4000 }, true).k, OPEN_K);
});

test("after an edit a diagram that fits is moved into view; one grown a little is zoomed out to fit", () => {
  const small = keptInView({ x: -500, y: 900, k: 1 }, canvas, { width: 200, height: 100 });
  assert.deepEqual(small, { x: 16, y: 600 - 16 - 100, k: 1 });
  const grown = keptInView({ x: 0, y: 0, k: 1 }, canvas, { width: 1200, height: 500 });
  assert.equal(grown.k, (1000 - 32) / 1200);
  // too big to be readable whole: left where it is
  assert.deepEqual(keptInView({ x: 5, y: 7, k: 1 }, canvas, { width: 5000, height: 5000 }), { x: 5, y: 7, k: 1 });
});

test("a zoom at the pointer keeps the diagram's point under it; the wheel zooms within bounds", () => {
  const before = { x: 30, y: -40, k: 0.5 };
  const after = zoomedAt(before, 300, 200, 2);
  // the diagram point under (300, 200) before is under it after
  const px = (300 - before.x) / before.k;
  const py = (200 - before.y) / before.k;
  assert.ok(Math.abs(after.x + px * after.k - 300) < 1e-9);
  assert.ok(Math.abs(after.y + py * after.k - 200) < 1e-9);
  assert.ok(wheelZoom(1, -100, false) > 1); // wheel up: in
  assert.ok(wheelZoom(1, 100, false) < 1);
  assert.equal(wheelZoom(MAX_K, -1000, false), MAX_K);
  assert.equal(wheelZoom(MIN_K, 1000, true), MIN_K);
});

test("the least pan that shows a box, with room to spare", () => {
  const c = { left: 0, top: 0, right: 1000, bottom: 600 };
  assert.deepEqual(panToShow(c, { left: 100, top: 100, right: 200, bottom: 200 }), { dx: 0, dy: 0 });
  assert.deepEqual(panToShow(c, { left: 950, top: 590, right: 1050, bottom: 650 }), { dx: -74, dy: -74 });
  // bigger than the canvas: its top-left edge shows
  assert.deepEqual(panToShow(c, { left: -500, top: -10, right: 2000, bottom: 100 }), { dx: 524, dy: 34 });
});

test("a lane's header stays on the lane's visible part", () => {
  const lane = { x: 0, y: 0, w: 2000, h: 3000, textW: 100, headH: 44 };
  // the whole lane's left part in view, top at the canvas's top: centred on the visible part
  assert.deepEqual(laneHeadPlace(lane, { x: 0, y: 0, k: 1 }, 1000), { cx: 500, dy: 0 });
  // scrolled down 500 px: the header comes down with it
  assert.deepEqual(laneHeadPlace(lane, { x: 0, y: -500, k: 1 }, 1000), { cx: 500, dy: 500 });
  // but never below the lane's end
  assert.equal(laneHeadPlace(lane, { x: 0, y: -9000, k: 1 }, 1000)?.dy, 3000 - 44);
  // only the lane's right end in view: the name stays inside the lane
  assert.deepEqual(laneHeadPlace(lane, { x: -1990, y: 0, k: 1 }, 1000), { cx: 2000 - 60, dy: 0 });
  // off the canvas: nothing to place
  assert.equal(laneHeadPlace(lane, { x: 1500, y: 0, k: 1 }, 1000), null);
});
