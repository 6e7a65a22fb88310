// Unit tests of the orthogonal router (run: npm test): routes go around the keep-out areas, leave
// and enter the way they are told, take the fewest bends, and stay in their bounds.
import assert from "node:assert/strict";
import { test } from "node:test";
import { type Pt, pathCrosses, type Rect, route, simplify } from "../src/draw/route";

function orthogonal(points: Pt[]): boolean {
  for (let i = 1; i < points.length; i++) {
    const p = points[i - 1];
    const q = points[i];
    if (Math.abs(p.x - q.x) > 0.01 && Math.abs(p.y - q.y) > 0.01) return false;
  }
  return true;
}

test("a free straight line stays straight", () => {
  const r = route({ x: 0, y: 0 }, "S", { x: 0, y: 100 }, "N", []);
  assert.deepEqual(r, [
    { x: 0, y: 0 },
    { x: 0, y: 100 },
  ]);
});

test("a box in the way is gone around, with two bends on each side of it at most", () => {
  const box: Rect = { x: -40, y: 40, w: 80, h: 20 };
  const r = route({ x: 0, y: 0 }, "S", { x: 0, y: 100 }, "N", [box]);
  assert.ok(r);
  assert.ok(orthogonal(r), JSON.stringify(r));
  assert.ok(!pathCrosses(box, r), JSON.stringify(r));
  assert.deepEqual(r[0], { x: 0, y: 0 });
  assert.deepEqual(r[r.length - 1], { x: 0, y: 100 });
  assert.ok(r.length <= 6, JSON.stringify(r));
});

test("the ends are left and entered the way they are told", () => {
  // leave to the right, come back into the right side of a box above (a loop's flow back)
  const boxes: Rect[] = [
    { x: 0, y: 180, w: 100, h: 40 },
    { x: 0, y: 0, w: 100, h: 40 },
    { x: 0, y: 90, w: 100, h: 40 },
  ];
  const r = route({ x: 100, y: 200 }, "E", { x: 100, y: 20 }, "E", boxes, { lead: 12 });
  assert.ok(r);
  assert.equal(r[1].y, 200);
  assert.ok(r[1].x > 100);
  const last = r[r.length - 2];
  assert.equal(last.y, 20);
  assert.ok(last.x > 100);
  assert.equal(r.length, 4, JSON.stringify(r)); // right, up, left: around the box between them
});

test("a wall of boxes with a gap: the route takes the gap", () => {
  const wall: Rect[] = [
    { x: -300, y: 50, w: 280, h: 20 },
    { x: 20, y: 50, w: 280, h: 20 },
  ];
  const r = route({ x: -100, y: 0 }, "S", { x: 100, y: 120 }, "N", wall);
  assert.ok(r);
  for (const w of wall) assert.ok(!pathCrosses(w, r), JSON.stringify(r));
  assert.ok(
    r.some((p) => p.x >= -20 && p.x <= 20),
    JSON.stringify(r),
  );
});

test("a box wider than the first look is still gone around", () => {
  const big: Rect = { x: -2000, y: 40, w: 3000, h: 30 };
  const r = route({ x: 0, y: 0 }, "S", { x: 0, y: 120 }, "N", [big]);
  assert.ok(r);
  assert.ok(!pathCrosses(big, r));
});

test("bounds are kept: no route out of them", () => {
  const box: Rect = { x: -10, y: 40, w: 300, h: 20 };
  const r = route({ x: 0, y: 0 }, "S", { x: 0, y: 100 }, "N", [box], { bounds: { x: -30, y: -50, w: 400, h: 300 } });
  assert.ok(r);
  assert.ok(
    r.every((p) => p.x >= -30 && p.x <= 370),
    JSON.stringify(r),
  );
  assert.equal(
    route({ x: 0, y: 0 }, "S", { x: 0, y: 100 }, "N", [box], { bounds: { x: -5, y: -50, w: 200, h: 300 } }),
    null,
  );
});

test("simplify drops repeated and collinear points", () => {
  assert.deepEqual(
    simplify([
      { x: 0, y: 0 },
      { x: 0, y: 0 },
      { x: 0, y: 5 },
      { x: 0, y: 10 },
      { x: 5, y: 10 },
    ]),
    [
      { x: 0, y: 0 },
      { x: 0, y: 10 },
      { x: 5, y: 10 },
    ],
  );
});
