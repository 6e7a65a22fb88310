import assert from "node:assert/strict";
import { test } from "node:test";
import { decodeBase64, depthRgba, findDepthPicture } from "../src/features/sim/depth-image";

test("the depth picture comes from the first component whose state carries one", () => {
  const states: [string, unknown][] = [
    ["DistanceRead", { distance_cm: 40, echo: true }],
    ["Eye", { depth_image: "AAEC", depth_size: [3, 1] }],
    ["Broken", { depth_image: "AAEC", depth_size: [0, 1] }],
    ["Nothing", null],
  ];
  assert.deepEqual(findDepthPicture(states), { component: "Eye", width: 3, height: 1, base64: "AAEC" });
  assert.equal(findDepthPicture([["DistanceRead", { distance_cm: 1 }]]), null);
});

test("grey bytes become RGBA, no reading dark blue, a short picture nothing", () => {
  const grey = decodeBase64("AAEC"); // 0, 1, 2
  assert.deepEqual(Array.from(grey), [0, 1, 2]);
  const rgba = depthRgba(grey, 3, 1);
  assert.deepEqual(Array.from(rgba ?? []), [20, 30, 60, 255, 1, 1, 1, 255, 2, 2, 2, 255]);
  assert.equal(depthRgba(grey, 2, 2), null);
});
