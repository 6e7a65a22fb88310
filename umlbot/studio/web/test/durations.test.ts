// Unit tests of the durations histogram (run: npm test): accuracy against exact nearest-rank
// percentiles, and memory that does not grow with the number of samples.
import assert from "node:assert/strict";
import { test } from "node:test";
import { Durations, MAX_BUCKETS, MAX_MS, MIN_MS, percentiles, REL_ERROR } from "../src/model/durations";

// exact nearest-rank percentile of the samples
function exact(samples: number[], q: number): number {
  const sorted = Float64Array.from(samples).sort();
  return sorted[Math.min(sorted.length, Math.max(1, Math.ceil(q * sorted.length))) - 1];
}

function near(got: number, want: number, what: string): void {
  assert.ok(Math.abs(got - want) <= REL_ERROR * Math.abs(want) * (1 + 1e-9), `${what}: ${got} vs exact ${want}`);
}

// a reproducible generator (xorshift32), so a failure can be replayed
function rng(seed: number): () => number {
  let x = seed >>> 0 || 1;
  return () => {
    x ^= x << 13;
    x >>>= 0;
    x ^= x >>> 17;
    x ^= x << 5;
    x >>>= 0;
    return x / 4294967296;
  };
}

test("small sets: the extremes and equal samples are exact, zeros are zeros", () => {
  const d = new Durations();
  for (const v of [5, 1, 4, 2, 3]) d.add(v);
  const [p50, p99] = percentiles(d);
  near(p50, 3, "p50");
  assert.equal(p99, 5); // the largest sample: clamped to it
  const same = new Durations();
  for (let i = 0; i < 100; i++) same.add(10);
  assert.deepEqual(percentiles(same), [10, 10]);
  assert.deepEqual(percentiles(new Durations()), [0, 0]);
  const zeros = new Durations();
  for (let i = 0; i < 60; i++) zeros.add(0);
  for (let i = 0; i < 40; i++) zeros.add(7);
  assert.equal(zeros.percentile(0.5), 0);
  near(zeros.percentile(0.99), 7, "p99 over zeros");
});

test("many samples of several shapes: p50 and p99 within 1 % of the exact values", () => {
  const next = rng(12345);
  const shapes: Record<string, () => number> = {
    uniform: () => 1 + next() * 99, // 1–100 ms
    lognormal: () =>
      Math.exp(Math.log(5) + 0.8 * Math.sqrt(-2 * Math.log(next() || 1e-12)) * Math.cos(2 * Math.PI * next())),
    bimodal: () => (next() < 0.9 ? 2 + next() : 200 + 50 * next()), // fast path, slow tail
    tiny: () => Math.round((0.001 + next() * 0.05) * 1000) / 1000, // µs resolution, as traced
    wide: () => MIN_MS * 10 ** (next() * 10), // 1 µs … 10 000 s
  };
  for (const [name, gen] of Object.entries(shapes)) {
    const d = new Durations();
    const samples: number[] = [];
    for (let i = 0; i < 200_000; i++) {
      const v = gen();
      samples.push(v);
      d.add(v);
    }
    assert.equal(d.count, samples.length);
    for (const q of [0.5, 0.9, 0.99, 0.999, 1]) near(d.percentile(q), exact(samples, q), `${name} q=${q}`);
  }
});

test("memory per node is bounded: the counters do not grow with the number of samples", () => {
  const next = rng(7);
  const d = new Durations();
  for (let i = 0; i < 10_000; i++) d.add(3 + 40 * next());
  const after10k = d.buckets;
  for (let i = 0; i < 1_000_000; i++) d.add(3 + 40 * next());
  assert.equal(d.buckets, after10k); // same range of durations: not one counter more
  assert.ok(after10k < 200, String(after10k)); // 3–43 ms spans ~134 buckets of 2 %
  // the worst case, every bucket used (and beyond the range), stays at MAX_BUCKETS
  const all = new Durations();
  for (let v = MIN_MS / 2; v < MAX_MS * 10; v *= 1.005) all.add(v);
  assert.equal(all.buckets, MAX_BUCKETS);
  assert.ok(MAX_BUCKETS < 1300, String(MAX_BUCKETS)); // ~10 KB of counters at most
  assert.equal(all.percentile(1), all.max);
});

test("a clone is independent of its original (replay snapshots)", () => {
  const d = new Durations(0);
  for (let i = 1; i <= 100; i++) d.add(i);
  const c = d.clone(1);
  for (let i = 0; i < 1000; i++) c.add(1000);
  assert.equal(d.count, 100);
  near(d.percentile(0.99), 99, "original p99");
  near(c.percentile(0.99), 1000, "clone p99");
  assert.equal(c.gen, 1);
});
