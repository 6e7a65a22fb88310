// The layout cache's page side (docs/studio.md, "Layout cache"): before ELK lays out a lane, the
// page asks the studio server for the layout kept under the SHA-256 of exactly what it would give
// ELK (and of this format and ELK's version); after ELK made one, it sends it there. A changed
// lane gives another key, so ELK runs as before; a missing server, a miss or an answer that does
// not fit the graph is ELK too. The server's side is umlbot/studio/layouts.py.

import { sha256 } from "@noble/hashes/sha2.js";
import { bytesToHex, utf8ToBytes } from "@noble/hashes/utils.js";
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
    const data = (await res.json()) as { layout?: Kept | null };
    if (!data.layout) return null; // none kept under this key
    if (!fits(data.layout, graph)) {
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

// SHA-256 by @noble/hashes (audited, no dependencies): the same key in every page, also where
// crypto.subtle is missing (a page not served from localhost or https is not a secure context).
export function sha256Hex(text: string): string {
  return bytesToHex(sha256(utf8ToBytes(text)));
}
