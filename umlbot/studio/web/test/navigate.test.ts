import assert from "node:assert/strict";
import { test } from "node:test";
import { hintText, offside, panTo } from "../src/features/navigate/edges-decide";

// the car's motion diagram: five lanes side by side, the last one wider
const lanes = [
  { name: "MoveForward", x: 0, w: 320 },
  { name: "MoveBackward", x: 320, w: 320 },
  { name: "TurnLeft", x: 640, w: 320 },
  { name: "TurnRight", x: 960, w: 320 },
  { name: "Stop", x: 1280, w: 590 },
];

test("the lanes mostly off the canvas are named at the edge they are off, nearest first", () => {
  const view = { x: 16, y: 0, k: 0.8 }; // a laptop's canvas, 750 px
  const off = offside(lanes, view, 750);
  assert.deepEqual(
    off.right.map((s) => s.name),
    ["TurnRight", "Stop"],
  );
  assert.deepEqual(off.left, []);
  assert.equal(hintText(off.right), "2 more lanes: TurnRight, Stop");
  assert.equal(hintText(lanes.slice(1)), "4 more lanes: MoveBackward, TurnLeft, TurnRight, +1");
  // a pan to the next one on the right shows it whole, at the right edge
  const x = panTo(off.right[0], view, 750, "right");
  const shown = offside(lanes, { ...view, x }, 750);
  assert.deepEqual(
    shown.right.map((s) => s.name),
    ["Stop"],
  );
  assert.deepEqual(
    shown.left.map((s) => s.name),
    ["MoveForward"],
  );
  // one lane wider than the canvas, filling it: it is not "off"
  assert.deepEqual(offside([{ name: "RaspberryPI", x: 0, w: 1600 }], { x: -700, y: 0, k: 1 }, 750), {
    left: [],
    right: [],
  });
  // all of it in view: nothing to say
  assert.deepEqual(offside(lanes, { x: 0, y: 0, k: 0.38 }, 750), { left: [], right: [] });
});
