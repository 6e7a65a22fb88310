// Reveal a node: centre it at a readable zoom and flash it (a diagnostic's click, the docs'
// screenshots). The user asked to see it: following would take the view away, so it stops.

import { zoomedAt } from "../../core/geometry";
import type { Studio } from "../../core/studio";

const READABLE_K = 0.8;
const REVEAL_K = 0.9;

export function reveal(studio: Studio, lane: string, node: string, tries = 0): void {
  const { bus, canvas } = studio;
  const v = canvas.shown();
  const g = canvas.el.querySelector<SVGGElement>(
    `g.node[data-lane="${CSS.escape(lane)}"][data-node="${CSS.escape(node)}"]`,
  );
  // inside a collapsed region: it opens, and the node is shown once drawn (within 10 s)
  if (!g && (tries > 0 || bus.request("region.show", lane, node)) && tries < 200) {
    setTimeout(() => reveal(studio, lane, node, tries + 1), 50);
    return;
  }
  if (!v?.view || !g) return;
  bus.emit("follow.set", false);
  canvas.uncull(g);
  if (v.view.k < READABLE_K) {
    const r = canvas.el.getBoundingClientRect();
    v.view = zoomedAt(v.view, r.width / 2, r.height / 2, REVEAL_K);
    canvas.apply(v);
  }
  canvas.uncull(g);
  const c = canvas.el.getBoundingClientRect();
  const b = g.getBoundingClientRect();
  v.view.x += c.left + c.width / 2 - (b.left + b.width / 2);
  v.view.y += c.top + c.height / 2 - (b.top + b.height / 2);
  canvas.apply(v);
  g.animate([{ opacity: 0.2 }, { opacity: 1 }, { opacity: 0.2 }, { opacity: 1 }], { duration: 900 });
}
