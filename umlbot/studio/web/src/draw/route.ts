// Orthogonal routing around boxes, for the lines the page draws itself: a flow to or from a node
// that keeps its place (a dragged node, a lane drawn before an edit) and a link of the component
// diagram once components keep their places. ELK routes everything else. Pure geometry (no DOM):
// unit-tested in test/route.test.ts.

export interface Pt {
  x: number;
  y: number;
}
export interface Rect {
  x: number;
  y: number;
  w: number;
  h: number;
}
/** The way a line leaves a point (`S`: downwards), or the side of a box it enters (`N`: from above). */
export type Dir = "N" | "S" | "E" | "W";

const STEP: Record<Dir, Pt> = { N: { x: 0, y: -1 }, S: { x: 0, y: 1 }, E: { x: 1, y: 0 }, W: { x: -1, y: 0 } };
const DIRS: Dir[] = ["N", "E", "S", "W"];
/** What a bend costs, in px of length: a route with fewer bends is preferred to a slightly shorter one. */
export const BEND_PX = 30;

export interface RouteOptions {
  /** how far the line goes straight out of `a` and into `b` before it may turn (px) */
  lead?: number;
  /** the area the route stays in (e.g. x ≥ 0: inside its lane) */
  bounds?: Rect;
  /** how far around the two ends the route first looks (px); doubled while no route is found */
  reach?: number;
  /** lines drawn already: running along one of them costs (OVERLAP_COST times its length more), crossing it does not */
  avoid?: Pt[][];
}

/** How much more a px of route costs where it runs along a line drawn already (it would read as that line). */
export const OVERLAP_COST = 2;
/** How far beside a line drawn already a route may run along it (px). */
const BESIDE_PX = 8;

/** Strictly inside (a point on the border is outside: a route may run along a keep-out's border). */
function inside(r: Rect, x: number, y: number): boolean {
  return x > r.x + 0.01 && x < r.x + r.w - 0.01 && y > r.y + 0.01 && y < r.y + r.h - 0.01;
}

/** Whether the segment p-q (horizontal or vertical) runs through the inside of `r`. */
export function crosses(r: Rect, p: Pt, q: Pt): boolean {
  const x0 = Math.min(p.x, q.x);
  const x1 = Math.max(p.x, q.x);
  const y0 = Math.min(p.y, q.y);
  const y1 = Math.max(p.y, q.y);
  return x0 < r.x + r.w - 0.01 && x1 > r.x + 0.01 && y0 < r.y + r.h - 0.01 && y1 > r.y + 0.01;
}

/** Whether the polyline `points` runs through the inside of `r`. */
export function pathCrosses(r: Rect, points: Pt[]): boolean {
  for (let i = 1; i < points.length; i++) if (crosses(r, points[i - 1], points[i])) return true;
  return false;
}

/** `r` grown by `by` px on every side. */
export function grow(r: Rect, by: number): Rect {
  return { x: r.x - by, y: r.y - by, w: r.w + 2 * by, h: r.h + 2 * by };
}

/** Drop repeated points and the middle of three points on one line. */
export function simplify(points: Pt[]): Pt[] {
  const out: Pt[] = [];
  for (const p of points) {
    const last = out[out.length - 1];
    if (last && Math.abs(last.x - p.x) < 0.01 && Math.abs(last.y - p.y) < 0.01) continue;
    if (out.length >= 2) {
      const a = out[out.length - 2];
      const b = last;
      if (
        (Math.abs(a.x - b.x) < 0.01 && Math.abs(b.x - p.x) < 0.01) ||
        (Math.abs(a.y - b.y) < 0.01 && Math.abs(b.y - p.y) < 0.01)
      ) {
        out[out.length - 1] = p;
        continue;
      }
    }
    out.push(p);
  }
  return out;
}

/** A small binary heap of [cost, state] (lowest cost first). */
class Heap {
  private cost: number[] = [];
  private item: number[] = [];
  get size(): number {
    return this.cost.length;
  }
  push(c: number, s: number): void {
    let i = this.cost.length;
    this.cost.push(c);
    this.item.push(s);
    while (i > 0) {
      const up = (i - 1) >> 1;
      if (this.cost[up] <= c) break;
      this.cost[i] = this.cost[up];
      this.item[i] = this.item[up];
      i = up;
    }
    this.cost[i] = c;
    this.item[i] = s;
  }
  pop(): [number, number] {
    const top: [number, number] = [this.cost[0], this.item[0]];
    const c = this.cost.pop()!;
    const s = this.item.pop()!;
    const n = this.cost.length;
    if (n) {
      let i = 0;
      for (;;) {
        const l = 2 * i + 1;
        if (l >= n) break;
        const r = l + 1;
        const m = r < n && this.cost[r] < this.cost[l] ? r : l;
        if (this.cost[m] >= c) break;
        this.cost[i] = this.cost[m];
        this.item[i] = this.item[m];
        i = m;
      }
      this.cost[i] = c;
      this.item[i] = s;
    }
    return top;
  }
}

function uniq(values: number[]): number[] {
  const sorted = values.slice().sort((p, q) => p - q);
  const out: number[] = [];
  for (const v of sorted) if (!out.length || v - out[out.length - 1] > 0.5) out.push(v);
  return out;
}

/**
 * An orthogonal route from `a` to `b` that runs through none of the `keepOut` areas (the boxes the
 * caller grew by the room it wants around them; a route may run along their borders). It leaves
 * `a` towards `from` and enters `b` through its side `into`, straight for `lead` px at each end;
 * of the routes on the grid of the areas' borders it is the one with the fewest bends, then the
 * shortest. Null when there is none (the ends are walled in).
 */
export function route(a: Pt, from: Dir, b: Pt, into: Dir, keepOut: Rect[], opts: RouteOptions = {}): Pt[] | null {
  const lead = opts.lead ?? 12;
  const a1 = { x: a.x + STEP[from].x * lead, y: a.y + STEP[from].y * lead };
  const b1 = { x: b.x + STEP[into].x * lead, y: b.y + STEP[into].y * lead };
  const arrive: Dir = into === "N" ? "S" : into === "S" ? "N" : into === "E" ? "W" : "E"; // the way into b
  let reach = opts.reach ?? 160;
  for (let tries = 0; tries < 6; tries++, reach *= 2) {
    let area: Rect = {
      x: Math.min(a1.x, b1.x) - reach,
      y: Math.min(a1.y, b1.y) - reach,
      w: Math.abs(a1.x - b1.x) + 2 * reach,
      h: Math.abs(a1.y - b1.y) + 2 * reach,
    };
    const bounds = opts.bounds;
    if (bounds) {
      const x0 = Math.max(area.x, bounds.x);
      const y0 = Math.max(area.y, bounds.y);
      area = {
        x: x0,
        y: y0,
        w: Math.min(area.x + area.w, bounds.x + bounds.w) - x0,
        h: Math.min(area.y + area.h, bounds.y + bounds.h) - y0,
      };
    }
    const near = keepOut.filter(
      (r) => r.x < area.x + area.w && r.x + r.w > area.x && r.y < area.y + area.h && r.y + r.h > area.y,
    );
    const found = search(a1, from, b1, arrive, near, area, segments(opts.avoid ?? [], area));
    if (found) return simplify([a, ...found, b]);
    if (
      bounds &&
      area.x <= bounds.x &&
      area.y <= bounds.y &&
      area.x + area.w >= bounds.x + bounds.w &&
      area.y + area.h >= bounds.y + bounds.h
    )
      break;
  }
  return null;
}

/** The horizontal and vertical segments of `lines` that reach into `area`. */
function segments(lines: Pt[][], area: Rect): { h: [number, number, number][]; v: [number, number, number][] } {
  const h: [number, number, number][] = []; // [y, x0, x1]
  const v: [number, number, number][] = []; // [x, y0, y1]
  for (const line of lines) {
    for (let i = 1; i < line.length; i++) {
      const p = line[i - 1];
      const q = line[i];
      if (
        Math.max(p.x, q.x) < area.x ||
        Math.min(p.x, q.x) > area.x + area.w ||
        Math.max(p.y, q.y) < area.y ||
        Math.min(p.y, q.y) > area.y + area.h
      )
        continue;
      if (Math.abs(p.y - q.y) < 0.5) h.push([p.y, Math.min(p.x, q.x), Math.max(p.x, q.x)]);
      else if (Math.abs(p.x - q.x) < 0.5) v.push([p.x, Math.min(p.y, q.y), Math.max(p.y, q.y)]);
    }
  }
  return { h, v };
}

/** The cheapest grid path from a1 (arrived going `from`) to b1 (leaving going `arrive`). */
function search(
  a1: Pt,
  from: Dir,
  b1: Pt,
  arrive: Dir,
  rects: Rect[],
  area: Rect,
  drawn: { h: [number, number, number][]; v: [number, number, number][] },
): Pt[] | null {
  const clampX = (v: number): number => Math.min(Math.max(v, area.x), area.x + area.w);
  const clampY = (v: number): number => Math.min(Math.max(v, area.y), area.y + area.h);
  // the grid: the ends, the keep-outs' borders, and beside each line drawn already (a way along it, not on it)
  const xs = uniq([
    a1.x,
    b1.x,
    area.x,
    area.x + area.w,
    ...rects.flatMap((r) => [clampX(r.x), clampX(r.x + r.w)]),
    ...drawn.v.flatMap(([x]) => [clampX(x - BESIDE_PX), clampX(x + BESIDE_PX)]),
  ]);
  const ys = uniq([
    a1.y,
    b1.y,
    area.y,
    area.y + area.h,
    ...rects.flatMap((r) => [clampY(r.y), clampY(r.y + r.h)]),
    ...drawn.h.flatMap(([y]) => [clampY(y - BESIDE_PX), clampY(y + BESIDE_PX)]),
  ]);
  const nx = xs.length;
  const ny = ys.length;
  const index = (list: number[], v: number): number => {
    let best = 0;
    for (let i = 1; i < list.length; i++) if (Math.abs(list[i] - v) < Math.abs(list[best] - v)) best = i;
    return best;
  };
  const si = index(xs, a1.x);
  const sj = index(ys, a1.y);
  const ti = index(xs, b1.x);
  const tj = index(ys, b1.y);
  // free grid points (the two ends always: a node's own keep-out may reach past its lead)
  const free = new Uint8Array(nx * ny);
  for (let i = 0; i < nx; i++) {
    for (let j = 0; j < ny; j++) {
      free[i * ny + j] = rects.some((r) => inside(r, xs[i], ys[j])) ? 0 : 1;
    }
  }
  free[si * ny + sj] = 1;
  free[ti * ny + tj] = 1;
  // a step between neighbouring grid points is open when its middle is in no keep-out
  // how many px of the step p-q run along a line drawn already
  const along = (x0: number, y0: number, x1: number, y1: number): number => {
    let n = 0;
    if (Math.abs(y0 - y1) < 0.5) {
      const lo = Math.min(x0, x1);
      const hi = Math.max(x0, x1);
      for (const [y, a, b] of drawn.h) if (Math.abs(y - y0) < 3) n += Math.max(0, Math.min(hi, b) - Math.max(lo, a));
    } else {
      const lo = Math.min(y0, y1);
      const hi = Math.max(y0, y1);
      for (const [x, a, b] of drawn.v) if (Math.abs(x - x0) < 3) n += Math.max(0, Math.min(hi, b) - Math.max(lo, a));
    }
    return n;
  };
  const open = (i: number, j: number, d: number): boolean => {
    const i2 = i + (d === 1 ? 1 : d === 3 ? -1 : 0);
    const j2 = j + (d === 2 ? 1 : d === 0 ? -1 : 0);
    if (i2 < 0 || i2 >= nx || j2 < 0 || j2 >= ny || !free[i2 * ny + j2]) return false;
    const mx = (xs[i] + xs[i2]) / 2;
    const my = (ys[j] + ys[j2]) / 2;
    return !rects.some((r) => inside(r, mx, my));
  };
  const states = nx * ny * 4;
  const best = new Float64Array(states).fill(Infinity);
  const prev = new Int32Array(states).fill(-1);
  const heap = new Heap();
  const start = (si * ny + sj) * 4 + DIRS.indexOf(from);
  best[start] = 0;
  heap.push(0, start);
  const goalDir = DIRS.indexOf(arrive);
  let goal = -1;
  while (heap.size) {
    const [c, s] = heap.pop();
    if (c > best[s]) continue;
    const d = s & 3;
    const cell = s >> 2;
    const i = Math.floor(cell / ny);
    const j = cell % ny;
    if (i === ti && j === tj) {
      const total = c + (d === goalDir ? 0 : BEND_PX);
      if (d === goalDir || (d + 2) % 4 !== goalDir) {
        if (d === goalDir) {
          goal = s;
          break;
        }
        // turn into b here: one more bend (a state of its own, so the cheapest one wins)
        const turned = cell * 4 + goalDir;
        if (total < best[turned]) {
          best[turned] = total;
          prev[turned] = s;
          heap.push(total, turned);
        }
      }
    }
    for (let nd = 0; nd < 4; nd++) {
      if (nd === (d + 2) % 4) continue; // no turning back
      if (!open(i, j, nd)) continue;
      const i2 = i + (nd === 1 ? 1 : nd === 3 ? -1 : 0);
      const j2 = j + (nd === 2 ? 1 : nd === 0 ? -1 : 0);
      const len = Math.abs(xs[i2] - xs[i]) + Math.abs(ys[j2] - ys[j]);
      const cost = c + len + OVERLAP_COST * along(xs[i], ys[j], xs[i2], ys[j2]) + (nd === d ? 0 : BEND_PX);
      const s2 = (i2 * ny + j2) * 4 + nd;
      if (cost < best[s2]) {
        best[s2] = cost;
        prev[s2] = s;
        heap.push(cost, s2);
      }
    }
  }
  if (goal < 0) return null;
  const path: Pt[] = [];
  for (let s = goal; s >= 0; s = prev[s]) {
    const cell = s >> 2;
    path.push({ x: xs[Math.floor(cell / ny)], y: ys[cell % ny] });
  }
  path.reverse();
  // the grid's nearest coordinates are the ends' own (they are on the grid)
  path[0] = { ...a1 };
  path[path.length - 1] = { ...b1 };
  return path;
}

/** The middle of the longest segment of `points` (where a line's label goes), and whether it is horizontal. */
export function middle(points: Pt[]): { x: number; y: number; horizontal: boolean } {
  let best = -1;
  let at = { x: points[0]?.x ?? 0, y: points[0]?.y ?? 0, horizontal: true };
  for (let i = 1; i < points.length; i++) {
    const p = points[i - 1];
    const q = points[i];
    const len = Math.abs(p.x - q.x) + Math.abs(p.y - q.y);
    if (len > best) {
      best = len;
      at = { x: (p.x + q.x) / 2, y: (p.y + q.y) / 2, horizontal: Math.abs(p.y - q.y) < 0.01 };
    }
  }
  return at;
}
