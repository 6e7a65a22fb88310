// How clean a drawn diagram is: how often its flows cross, and how many of its guard labels overlap
// another label or are struck through by a flow. Pure (test/quality.test.ts); the page computes it
// for the diagram shown (`window.__studio.quality(id)`).

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

/** The corner points of an SVG path's `d` as the renderer writes it (M, L and Q's end points). */
export function pathPoints(d: string): Pt[] {
  const out: Pt[] = [];
  const re = /([MLQ])\s*([-\d.e]+)[ ,]+([-\d.e]+)(?:\s+([-\d.e]+)[ ,]+([-\d.e]+))?/g;
  for (let m = re.exec(d); m; m = re.exec(d)) {
    if (m[1] === "Q") out.push({ x: Number(m[4]), y: Number(m[5]) });
    else out.push({ x: Number(m[2]), y: Number(m[3]) });
  }
  return out;
}

function cross(a: Pt, b: Pt, c: Pt, d: Pt): boolean {
  const o = (p: Pt, q: Pt, r: Pt): number => (q.x - p.x) * (r.y - p.y) - (q.y - p.y) * (r.x - p.x);
  const d1 = o(c, d, a);
  const d2 = o(c, d, b);
  const d3 = o(a, b, c);
  const d4 = o(a, b, d);
  return ((d1 > 0 && d2 < 0) || (d1 < 0 && d2 > 0)) && ((d3 > 0 && d4 < 0) || (d3 < 0 && d4 > 0));
}

/** Proper crossings between segments of different flows (touching ends, shared ports: none). */
export function crossings(flows: Pt[][]): number {
  let n = 0;
  for (let i = 0; i < flows.length; i++) {
    for (let j = i + 1; j < flows.length; j++) {
      const a = flows[i];
      const b = flows[j];
      for (let p = 1; p < a.length; p++)
        for (let q = 1; q < b.length; q++) if (cross(a[p - 1], a[p], b[q - 1], b[q])) n++;
    }
  }
  return n;
}

function overlap(a: Rect, b: Rect): boolean {
  return a.x < b.x + b.w && b.x < a.x + a.w && a.y < b.y + b.h && b.y < a.y + a.h;
}

function segmentHits(r: Rect, a: Pt, b: Pt): boolean {
  const corners = [
    { x: r.x, y: r.y },
    { x: r.x + r.w, y: r.y },
    { x: r.x + r.w, y: r.y + r.h },
    { x: r.x, y: r.y + r.h },
  ];
  const inside = (p: Pt): boolean => p.x > r.x && p.x < r.x + r.w && p.y > r.y && p.y < r.y + r.h;
  if (inside(a) || inside(b)) return true;
  for (let i = 0; i < 4; i++) if (cross(a, b, corners[i], corners[(i + 1) % 4])) return true;
  return false;
}

/** Labels that overlap another label, or that another flow runs through (`own[i]`: the index of
 * label i's own flow, which an inline guard sits on by design: its halo breaks the line). */
export function labelProblems(labels: Rect[], flows: Pt[][], own: number[] = []): number {
  let n = 0;
  labels.forEach((r, i) => {
    const hit =
      labels.some((o, j) => j !== i && overlap(r, o)) ||
      flows.some((f, fi) => fi !== own[i] && f.some((p, k) => k > 0 && segmentHits(r, f[k - 1], p)));
    if (hit) n++;
  });
  return n;
}
