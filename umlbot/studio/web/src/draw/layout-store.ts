// The layout cache's page side (docs/studio.md, "Layout cache"): before ELK lays out a lane, the
// page asks the studio server for the layout kept under the SHA-256 of exactly what it would give
// ELK (and of this format and ELK's version); after ELK made one, it sends it there. A changed
// lane gives another key, so ELK runs as before; a missing server, a miss or an answer that does
// not fit the graph is ELK too. The server's side is umlbot/studio/layouts.py.

import type { ElkNode } from "elkjs/lib/elk-api.js";
import { version as ELK_VERSION } from "elkjs/package.json";

/** What the key covers besides ELK's input: bump the number when the kept fields change. */
export const LAYOUT_FORMAT = `umlbot-lane-layout 1 elkjs ${ELK_VERSION}`;

/** How this page's lanes were laid out (window.__studio.layouts; the browser tests read it). */
export const layoutStats = {
  /** layouts ELK made */
  elk: 0,
  /** layouts taken from the cache instead */
  cached: 0,
  /** layouts the server took */
  kept: 0,
  /** answers from the cache that did not fit their graph (ELK ran) */
  unfit: 0,
  /** background layouts of a cached lane (ELK's warm-up; src/draw/layout.ts) */
  warmed: 0,
  /** of those, layouts that differed from the cached one */
  differ: 0,
};

interface P {
  x: number;
  y: number;
}
/** A lane's layout as kept: only what the page draws from. */
interface Kept {
  width: number;
  height: number;
  children: { id: string; x: number; y: number }[];
  edges: {
    id: string;
    sections: { startPoint: P; endPoint: P; bendPoints?: P[] }[];
    labels?: { x: number; y: number; width: number; height: number }[];
  }[];
}

const pt = (p: P): P => ({ x: p.x, y: p.y });

/** ELK's answer cut to what the page reads from it (`layoutLane`). */
export function keptPart(out: ElkNode): Kept {
  return {
    width: out.width ?? 0,
    height: out.height ?? 0,
    children: (out.children ?? []).map((c) => ({ id: c.id, x: c.x ?? 0, y: c.y ?? 0 })),
    edges: (out.edges ?? []).map((e) => {
      const edge: Kept["edges"][number] = {
        id: e.id,
        sections: (e.sections ?? []).map((s) => {
          const section: Kept["edges"][number]["sections"][number] = {
            startPoint: pt(s.startPoint),
            endPoint: pt(s.endPoint),
          };
          if (s.bendPoints) section.bendPoints = s.bendPoints.map(pt);
          return section;
        }),
      };
      if (e.labels)
        edge.labels = e.labels.map((l) => ({ x: l.x ?? 0, y: l.y ?? 0, width: l.width ?? 0, height: l.height ?? 0 }));
      return edge;
    }),
  };
}

/** Whether a kept layout has exactly the graph's nodes and flows (and a label box where ELK had one). */
function fits(kept: Kept, graph: ElkNode): boolean {
  const nodes = graph.children ?? [];
  const edges = graph.edges ?? [];
  if (!Array.isArray(kept.children) || !Array.isArray(kept.edges)) return false;
  if (kept.children.length !== nodes.length || kept.edges.length !== edges.length) return false;
  const ids = new Set(nodes.map((n) => n.id));
  if (!kept.children.every((c) => ids.has(c.id))) return false;
  const labelled = new Map(edges.map((e) => [e.id, (e.labels ?? []).length]));
  return kept.edges.every((e) => labelled.has(e.id) && (e.labels ?? []).length === labelled.get(e.id));
}

/** The key of a lane's layout: SHA-256 (hex) of LAYOUT_FORMAT and ELK's input as JSON. */
export function layoutKey(graph: ElkNode): string {
  return sha256Hex(`${LAYOUT_FORMAT}\n${JSON.stringify(graph)}`);
}

/** Where the cache is: the studio server that served the page (none for a page opened as a file). */
const usable = (): boolean => typeof location !== "undefined" && /^https?:$/.test(location.protocol);

/** The layout kept for `graph` under `key`, or null (ask ELK). */
export async function storedLayout(key: string, graph: ElkNode): Promise<ElkNode | null> {
  if (!usable()) return null;
  try {
    const res = await fetch(`/api/layout/${key}`, { cache: "no-store" });
    if (!res.ok) return null;
    const data = (await res.json()) as { layout?: Kept };
    if (!data.layout || !fits(data.layout, graph)) {
      layoutStats.unfit += 1;
      return null;
    }
    layoutStats.cached += 1;
    return data.layout as unknown as ElkNode;
  } catch {
    return null;
  }
}

/** Send ELK's layout of a lane to the server's cache (in the background; a failure is no cache). */
export function keepLayout(key: string, out: ElkNode): void {
  if (!usable()) return;
  void fetch("/api/layout", {
    method: "POST",
    headers: { "Content-Type": "application/json" },
    body: JSON.stringify({ key, layout: keptPart(out) }),
  })
    .then(async (res) => {
      if (res.ok && ((await res.json()) as { kept?: boolean }).kept) layoutStats.kept += 1;
    })
    .catch(() => undefined);
}

// SHA-256 (FIPS 180-4) of a string's UTF-8 bytes: the same key in every page, also where
// crypto.subtle is missing (a page not served from localhost or https is not a secure context).
const K = new Uint32Array([
  0x428a2f98, 0x71374491, 0xb5c0fbcf, 0xe9b5dba5, 0x3956c25b, 0x59f111f1, 0x923f82a4, 0xab1c5ed5, 0xd807aa98,
  0x12835b01, 0x243185be, 0x550c7dc3, 0x72be5d74, 0x80deb1fe, 0x9bdc06a7, 0xc19bf174, 0xe49b69c1, 0xefbe4786,
  0x0fc19dc6, 0x240ca1cc, 0x2de92c6f, 0x4a7484aa, 0x5cb0a9dc, 0x76f988da, 0x983e5152, 0xa831c66d, 0xb00327c8,
  0xbf597fc7, 0xc6e00bf3, 0xd5a79147, 0x06ca6351, 0x14292967, 0x27b70a85, 0x2e1b2138, 0x4d2c6dfc, 0x53380d13,
  0x650a7354, 0x766a0abb, 0x81c2c92e, 0x92722c85, 0xa2bfe8a1, 0xa81a664b, 0xc24b8b70, 0xc76c51a3, 0xd192e819,
  0xd6990624, 0xf40e3585, 0x106aa070, 0x19a4c116, 0x1e376c08, 0x2748774c, 0x34b0bcb5, 0x391c0cb3, 0x4ed8aa4a,
  0x5b9cca4f, 0x682e6ff3, 0x748f82ee, 0x78a5636f, 0x84c87814, 0x8cc70208, 0x90befffa, 0xa4506ceb, 0xbef9a3f7,
  0xc67178f2,
]);

export function sha256Hex(text: string): string {
  const data = new TextEncoder().encode(text);
  const bits = data.length * 8;
  const padded = new Uint8Array((((data.length + 9 + 63) >> 6) << 6) >>> 0);
  padded.set(data);
  padded[data.length] = 0x80;
  const view = new DataView(padded.buffer);
  view.setUint32(padded.length - 8, Math.floor(bits / 0x100000000));
  view.setUint32(padded.length - 4, bits >>> 0);
  const h = new Uint32Array([
    0x6a09e667, 0xbb67ae85, 0x3c6ef372, 0xa54ff53a, 0x510e527f, 0x9b05688c, 0x1f83d9ab, 0x5be0cd19,
  ]);
  const w = new Uint32Array(64);
  const rotr = (x: number, n: number): number => (x >>> n) | (x << (32 - n));
  for (let off = 0; off < padded.length; off += 64) {
    for (let i = 0; i < 16; i++) w[i] = view.getUint32(off + i * 4);
    for (let i = 16; i < 64; i++) {
      const a = w[i - 15];
      const b = w[i - 2];
      const s0 = rotr(a, 7) ^ rotr(a, 18) ^ (a >>> 3);
      const s1 = rotr(b, 17) ^ rotr(b, 19) ^ (b >>> 10);
      w[i] = (w[i - 16] + s0 + w[i - 7] + s1) >>> 0;
    }
    let [a, b, c, d, e, f, g, hh] = h;
    for (let i = 0; i < 64; i++) {
      const t1 = (hh + (rotr(e, 6) ^ rotr(e, 11) ^ rotr(e, 25)) + ((e & f) ^ (~e & g)) + K[i] + w[i]) >>> 0;
      const t2 = ((rotr(a, 2) ^ rotr(a, 13) ^ rotr(a, 22)) + ((a & b) ^ (a & c) ^ (b & c))) >>> 0;
      hh = g;
      g = f;
      f = e;
      e = (d + t1) >>> 0;
      d = c;
      c = b;
      b = a;
      a = (t1 + t2) >>> 0;
    }
    h[0] += a;
    h[1] += b;
    h[2] += c;
    h[3] += d;
    h[4] += e;
    h[5] += f;
    h[6] += g;
    h[7] += hh;
  }
  return Array.from(h, (x) => x.toString(16).padStart(8, "0")).join("");
}
