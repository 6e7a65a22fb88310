// A node's durations over the whole run in bounded memory: a log-bucket histogram (the scheme of
// DDSketch, close to HdrHistogram). A reported percentile is the nearest-rank percentile of every
// sample seen, within REL_ERROR (1 %) of the exact value for durations from MIN_MS (1 µs, the
// trace's resolution) to MAX_MS (24 h); 0 and the smallest and largest sample are kept exactly
// (no answer lies outside them). Memory per node: at most MAX_BUCKETS counters (about 10 KB), usually
// a few dozen (only the range of buckets the node's durations fall in is allocated), whatever the
// number of samples; a percentile walks that range (not every sample).
//
// Replay snapshots share these objects: `gen` says which generation of the state owns one; the
// state clones a histogram from an older generation before it adds to it (copy on write).

export const REL_ERROR = 0.01;
export const MIN_MS = 0.001;
export const MAX_MS = 86_400_000;
const GAMMA = (1 + REL_ERROR) / (1 - REL_ERROR);
const LOG_GAMMA = Math.log(GAMMA);
const TOP = Math.ceil(Math.log(MAX_MS / MIN_MS) / LOG_GAMMA); // longer durations count as MAX_MS
/** The most counters one node's histogram can hold. */
export const MAX_BUCKETS = TOP + 1;
const SLACK = 8; // buckets allocated beyond the one that made the range grow
const EMPTY = new Float64Array(0);

// Bucket k > 0 holds (MIN_MS·γ^(k-1), MIN_MS·γ^k], bucket 0 holds (0, MIN_MS].
function bucketOf(ms: number): number {
  if (ms <= MIN_MS) return 0;
  return Math.min(TOP, Math.max(0, Math.ceil(Math.log(ms / MIN_MS) / LOG_GAMMA)));
}

// The value whose relative distance to every value of bucket k is at most REL_ERROR.
function bucketValue(k: number): number {
  return (MIN_MS * 2 * GAMMA ** k) / (GAMMA + 1);
}

export class Durations {
  count = 0;
  zeros = 0; // samples <= 0 ms
  min = Infinity;
  max = -Infinity;
  private lo = 0; // bucket of counts[0]
  private counts: Float64Array = EMPTY;

  constructor(public gen = 0) {}

  /** Counters allocated (the memory this node's durations take). */
  get buckets(): number {
    return this.counts.length;
  }

  add(ms: number): void {
    this.count += 1;
    if (ms < this.min) this.min = ms;
    if (ms > this.max) this.max = ms;
    if (!(ms > 0)) {
      this.zeros += 1;
      return;
    }
    const k = bucketOf(ms);
    if (k < this.lo || k >= this.lo + this.counts.length) this.grow(k);
    this.counts[k - this.lo] += 1;
  }

  clone(gen: number): Durations {
    const c = new Durations(gen);
    c.count = this.count;
    c.zeros = this.zeros;
    c.min = this.min;
    c.max = this.max;
    c.lo = this.lo;
    c.counts = this.counts.slice();
    return c;
  }

  /** Nearest-rank percentile (q in (0, 1]), within REL_ERROR; 0 without samples. */
  percentile(q: number): number {
    if (this.count === 0) return 0;
    const rank = Math.min(this.count, Math.max(1, Math.ceil(q * this.count)));
    if (rank === this.count) return this.max; // the extremes are kept exactly
    if (rank === 1) return this.min;
    let value = this.max;
    if (rank <= this.zeros) value = 0;
    else {
      let seen = this.zeros;
      for (let i = 0; i < this.counts.length; i++) {
        seen += this.counts[i];
        if (seen >= rank) {
          value = bucketValue(this.lo + i);
          break;
        }
      }
    }
    return Math.min(this.max, Math.max(this.min, value));
  }

  private grow(k: number): void {
    const n = this.counts.length;
    const lo = n === 0 || k < this.lo ? Math.max(0, k - SLACK) : this.lo;
    const end = n === 0 || k >= this.lo + n ? Math.min(MAX_BUCKETS, k + 1 + SLACK) : this.lo + n;
    const counts = new Float64Array(end - lo);
    if (n) counts.set(this.counts, this.lo - lo);
    this.lo = lo;
    this.counts = counts;
  }
}

/** p50 and p99 of a node's durations (nearest rank, within REL_ERROR). */
export function percentiles(d: Durations): [number, number] {
  return [d.percentile(0.5), d.percentile(0.99)];
}
