// Collapsible regions (draw/regions.ts): which regions the user opened, the click or key (Enter,
// Space) on a collapsed region's box that opens it, and what opens one by itself: a node inside
// it revealed (a diagnostic's click) or edited. Opening one draws the diagram again, the view
// where it was; the keyboard's focus goes to the region's first node.

import type { Studio } from "../../core/studio";
import { collapseDiagram, isRegionId, laneRegions } from "../../draw/regions";
import type { ModelDiagram, ModelView } from "../../model/types";

export function install(studio: Studio): void {
  const { bus, store, hooks, canvas } = studio;
  const el = canvas.el;
  /** regions opened by the user: "<diagram>\n<lane>\n<region id>" */
  const open = new Set<string>();
  /** diagrams with every region open */
  const allOpen = new Set<string>();
  const key = (d: string, lane: string, region: string): string => `${d}\n${lane}\n${region}`;
  let focusAfter: { lane: string; node: string } | null = null;

  bus.on("layout.collapse", (d: ModelDiagram) =>
    allOpen.has(d.id) ? d : collapseDiagram(d, (lane, r) => open.has(key(d.id, lane, r))),
  );

  const diagramOf = (lane: string): string | undefined => store.laneDiagram.get(lane);
  /** the collapsed region (of the drawing shown) that holds `node`, if any */
  const holder = (lane: string, node: string): string | null => {
    const d = diagramOf(lane);
    const l = store.model?.diagrams.find((x) => x.id === d)?.lanes.find((x) => x.name === lane);
    if (!d || !l || allOpen.has(d)) return null;
    const r = laneRegions(l).find((x) => x.members.includes(node) && !open.has(key(d, lane, x.id)));
    return r ? r.id : null;
  };

  const expand = (lane: string, region: string, focus: boolean): void => {
    const d = diagramOf(lane);
    if (!d) return;
    open.add(key(d, lane, region));
    focusAfter = focus ? { lane, node: region.slice("region:".length) } : null;
    bus.emit("model.relayout");
  };
  /** `node` drawn: open the collapsed region that holds it; true when one was opened */
  const show = (lane: string, node: string): boolean => {
    const r = holder(lane, node);
    if (r) expand(lane, r, false);
    return r !== null;
  };
  bus.on("region.show", show);
  hooks.regions = (id, how) => {
    if (how === "open") allOpen.add(id);
    else {
      allOpen.delete(id);
      for (const k of [...open]) if (k.startsWith(`${id}\n`)) open.delete(k);
    }
    bus.emit("model.relayout");
  };

  const regionBox = (t: EventTarget | null): SVGGElement | null => {
    const g = (t as Element | null)?.closest?.<SVGGElement>("g.node");
    return g && isRegionId(g.dataset.node ?? "") ? g : null;
  };
  // (capture: before selection, connection and the keyboard's own handlers see the box; a press
  // on it neither selects nor drags it, nor starts a flow: it is no node of the model)
  el.addEventListener(
    "pointerdown",
    (ev) => {
      if (regionBox(ev.target)) ev.stopPropagation();
    },
    true,
  );
  el.addEventListener(
    "click",
    (ev) => {
      const g = regionBox(ev.target);
      if (!g) return;
      ev.stopPropagation();
      expand(g.dataset.lane ?? "", g.dataset.node ?? "", false);
    },
    true,
  );
  el.addEventListener(
    "keydown",
    (ev) => {
      if (ev.key !== "Enter" && ev.key !== " ") return;
      const g = regionBox(ev.target);
      if (!g || ev.ctrlKey || ev.metaKey || ev.altKey) return;
      ev.preventDefault();
      ev.stopPropagation();
      expand(g.dataset.lane ?? "", g.dataset.node ?? "", true);
    },
    true,
  );
  // the region's first node takes the focus once it is drawn
  bus.on("frame.render", () => {
    if (!focusAfter) return;
    const g = el.querySelector<SVGGElement>(
      `g.node[data-lane="${CSS.escape(focusAfter.lane)}"][data-node="${CSS.escape(focusAfter.node)}"]`,
    );
    if (!g) return;
    focusAfter = null;
    g.focus({ preventScroll: true });
  });

  // an edit inside a collapsed region opens it: the nodes it changed are drawn
  let before: ModelView | null = null;
  bus.on("model.edited", (m) => {
    if (m && before) {
      for (const d of before.diagrams) {
        for (const l of d.lanes) {
          const now = m.diagrams.find((x) => x.id === d.id)?.lanes.find((x) => x.name === l.name);
          if (!now) continue;
          const was = new Map(l.nodes.map((n) => [n.id, JSON.stringify(n)]));
          const edges = (lane: typeof l, id: string): string =>
            JSON.stringify(lane.edges.filter((e) => e.source === id || e.target === id));
          for (const r of laneRegions(l)) {
            if (open.has(key(d.id, l.name, r.id)) || allOpen.has(d.id)) continue;
            const changed = r.members.some((id) => {
              const n = now.nodes.find((x) => x.id === id);
              return !n || JSON.stringify(n) !== was.get(id) || edges(now, id) !== edges(l, id);
            });
            if (changed) open.add(key(d.id, l.name, r.id));
          }
        }
      }
    }
    before = m;
  });
  bus.on("model.shown", (m) => {
    before = m;
  });
}
