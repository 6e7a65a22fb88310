import assert from "node:assert/strict";
import { test } from "node:test";
import { crossings, labelProblems, pathPoints } from "../src/draw/quality";

test("crossings count flows that cross, not flows that meet", () => {
  const h = [
    { x: 0, y: 5 },
    { x: 10, y: 5 },
  ];
  const v = [
    { x: 5, y: 0 },
    { x: 5, y: 10 },
  ];
  const meets = [
    { x: 10, y: 5 },
    { x: 20, y: 5 },
  ];
  assert.equal(crossings([h, v]), 1);
  assert.equal(crossings([h, meets]), 0);
  assert.deepEqual(pathPoints("M1,2 L3,4 Q5,6 7,8 L9,10"), [
    { x: 1, y: 2 },
    { x: 3, y: 4 },
    { x: 7, y: 8 },
    { x: 9, y: 10 },
  ]);
});

test("a label struck by a flow or on another label is a problem", () => {
  const flow = [
    { x: 0, y: 5 },
    { x: 100, y: 5 },
  ];
  assert.equal(labelProblems([{ x: 10, y: 0, w: 20, h: 10 }], [flow]), 1);
  assert.equal(labelProblems([{ x: 10, y: 0, w: 20, h: 10 }], [flow], [0]), 0); // its own flow: inline
  assert.equal(labelProblems([{ x: 10, y: 8, w: 20, h: 10 }], [flow]), 0);
  assert.equal(
    labelProblems(
      [
        { x: 0, y: 20, w: 20, h: 10 },
        { x: 10, y: 25, w: 20, h: 10 },
      ],
      [],
    ),
    2,
  );
});
