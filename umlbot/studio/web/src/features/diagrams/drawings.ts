// The model's drawings: a new model is laid out and drawn diagram by diagram (the shown one
// first); the old drawings stay on screen until their new ones are ready (an edit redraws in
// place), and each keeps its pan and zoom.

import { $ } from "../../core/dom";
import type { View } from "../../core/geometry";
import type { Studio } from "../../core/studio";
import { layoutActivity, layoutComponents } from "../../draw/layout";
import type { DiagramView } from "../../draw/render";
import { ModelIndex } from "../../model/state";
import type { Diagnostic, ModelView } from "../../model/types";
import type { DiagramList } from "./list";
import { diagramIds, diagramInHash, firstDiagram } from "./which";

export class Drawings {
  private messageEl = $<HTMLElement>("#canvas-message");
  /** what the page is doing until the first diagram is drawn (shown by index.html from the start) */
  private progressEl = $<HTMLElement>("#canvas-progress");
  /** bumped by each model: a layout of an older one is dropped */
  private generation = 0;
  /** drawings shown until their redraw is ready */
  private replaced = new Map<string, DiagramView>();
  /** pan/zoom kept across redraws */
  private savedViews = new Map<string, View>();
  /** the edit version the model being drawn is of */
  private drawnVersion = -1;

  constructor(
    private studio: Studio,
    private list: DiagramList,
  ) {}

  /** Show model `m`; `fromEditor`: the editor's own answer (it draws its panels itself after). */
  set(m: ModelView | null, diagnostics: Diagnostic[], fromEditor = false): void {
    const { bus, store, hooks, canvas, renderer } = this.studio;
    this.drawnVersion = hooks.edit?.version ?? -1;
    this.generation += 1;
    const gen = this.generation;
    store.model = m;
    store.index = new ModelIndex(m);
    store.live.index = store.index;
    renderer.reset(m);
    // The old drawings stay on screen until their new ones are ready (an edit redraws in place).
    for (const v of canvas.views.values()) if (v.view) this.savedViews.set(v.id, v.view);
    for (const [id, v] of canvas.views) {
      // a drawing that was itself waiting for its redraw is dropped for the newer one
      this.replaced.get(id)?.svg.remove();
      this.replaced.set(id, v);
    }
    canvas.views = new Map();
    store.laneDiagram = new Map();
    for (const d of m?.diagrams ?? []) for (const l of d.lanes) store.laneDiagram.set(l.name, d.id);

    this.list.build(m, (id) => this.select(id));
    bus.emit("diagnostics.set", diagnostics);

    if (!m) {
      for (const v of this.replaced.values()) v.svg.remove();
      this.replaced = new Map();
      this.messageEl.textContent = "The model does not compile: see the diagnostics.";
      bus.emit("model.missing", this.messageEl);
      this.messageEl.hidden = false;
      this.progressEl.hidden = true;
      hooks.ready = true;
      return;
    }
    this.messageEl.hidden = true;
    bus.emit("model.shown", m);
    for (const [id, v] of this.replaced) {
      if (!diagramIds(m).includes(id)) {
        v.svg.remove();
        this.replaced.delete(id);
      }
    }
    const first = firstDiagram(m, diagramInHash(location.hash), canvas.current);
    if (!hooks.ready) {
      const d = m.diagrams.find((x) => `${x.id}` === first);
      const nodes = d ? d.lanes.reduce((n, l) => n + l.nodes.length, 0) : 0;
      this.progressEl.querySelector(".what")!.textContent = d
        ? `Laying out ${d.title} (${nodes} node${nodes === 1 ? "" : "s"})…`
        : "Laying out the components…";
    }
    const was = canvas.current;
    canvas.current = "";
    this.select(first, !(fromEditor && first === was));
    void this.layoutAll(m, first, gen);
  }

  /** Show diagram `id`; `tellEditor`: the editor's panels follow (not for its own answer). */
  select(id: string, tellEditor = true): void {
    const { bus, store, canvas } = this.studio;
    if (!diagramIds(store.model).includes(id)) return;
    canvas.current = id;
    this.list.markSelected(id);
    for (const [vid, v] of canvas.views) v.svg.style.display = vid === id ? "" : "none";
    for (const [vid, v] of this.replaced) v.svg.style.display = vid === id ? "" : "none";
    if (tellEditor) bus.emit("diagram.shown", id);
    const v = canvas.views.get(id);
    if (v && !v.view) canvas.fit(v);
    bus.emit("follow.due"); // another diagram: its node that ran last, at once
    if (diagramInHash(location.hash) !== id) history.replaceState(null, "", `#diagram=${encodeURIComponent(id)}`);
  }

  private async layoutAll(m: ModelView, first: string, gen: number): Promise<void> {
    const { bus, store, hooks, canvas, renderer, frames } = this.studio;
    const order = [first, ...diagramIds(m).filter((id) => id !== first)];
    for (const id of order) {
      try {
        const t0 = performance.now();
        let view: DiagramView | null;
        let t1: number;
        const positions = bus.request("layout.positions", id) ?? {};
        if (id === "components") {
          const layout = await layoutComponents(m, positions);
          if (gen !== this.generation) return;
          t1 = performance.now();
          view = renderer.buildComponents(layout, m);
        } else {
          const whole = m.diagrams.find((x) => x.id === id)!;
          const d = bus.request("layout.collapse", whole) ?? whole;
          const layout = await layoutActivity(d, positions);
          if (gen !== this.generation) return;
          t1 = performance.now();
          view = await renderer.buildActivity(layout, () => gen !== this.generation, this.replaced.get(id));
          if (!view || gen !== this.generation) return;
        }
        const current = id === canvas.current;
        view.svg.style.display = current ? "" : "none";
        const was = this.replaced.get(id);
        if (was && was.svg !== view.svg) was.svg.remove();
        if (view.svg.parentNode !== canvas.el) canvas.el.append(view.svg);
        this.replaced.delete(id);
        canvas.views.set(id, view);
        const saved = this.savedViews.get(id);
        if (saved) {
          view.view = { ...saved };
          if (hooks.edit) canvas.keepInView(view);
          canvas.apply(view);
        } else if (current) canvas.fit(view);
        if (current) bus.emit("follow.due"); // drawn: where is the robot?
        renderer.adoptFresh(store.live);
        const sel = bus.request("selection.highlight");
        if (sel && current) canvas.showElement(view, sel);
        if (hooks.edit && current) hooks.edit.drawn = this.drawnVersion;
        store.live.dirtyOrch = true;
        frames.schedule();
        console.debug(
          `studio: ${id} laid out in ${(t1 - t0).toFixed(0)} ms, drawn in ${(performance.now() - t1).toFixed(0)} ms`,
        );
        if (id === first) {
          // ready once the frame that first paints it is over
          this.progressEl.hidden = true;
          requestAnimationFrame(() =>
            requestAnimationFrame(() => {
              hooks.ready = true;
            }),
          );
        }
      } catch (err) {
        console.error(`studio: layout of ${id} failed`, err);
        if (id === first) {
          this.progressEl.hidden = true;
          hooks.ready = true;
        }
      }
    }
  }
}
