// The quality figures of a drawing, read from its SVG (lane by lane: a flow stays in its lane).

import { crossings, labelProblems, type Pt, pathPoints, type Rect } from "../../draw/quality";

export function measureQuality(viewport: SVGGElement): { crossings: number; labels: number; flows: number } {
  let c = 0;
  let l = 0;
  let flows = 0;
  for (const lane of viewport.querySelectorAll("g.lane")) {
    const lines: Pt[][] = [];
    const boxes: Rect[] = [];
    const own: number[] = [];
    for (const e of lane.querySelectorAll("g.edge")) {
      const d = e.querySelector("path.line")?.getAttribute("d");
      if (!d) continue;
      lines.push(pathPoints(d));
      const t = e.querySelector<SVGGraphicsElement>("text.elabel");
      if (t?.textContent) {
        const b = t.getBBox();
        boxes.push({ x: b.x, y: b.y, w: b.width, h: b.height });
        own.push(lines.length - 1);
      }
    }
    flows += lines.length;
    c += crossings(lines);
    l += labelProblems(boxes, lines, own);
  }
  return { crossings: c, labels: l, flows };
}
