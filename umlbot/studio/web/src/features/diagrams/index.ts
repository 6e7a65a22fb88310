// The diagrams: the model's drawings, the list to pick one, the address that names the shown one
// (`#diagram=<id>`), and the banner that says when an edit broke the model (the last good drawing
// stays).

import { $ } from "../../core/dom";
import type { Studio } from "../../core/studio";
import type { Diagnostic, ModelView } from "../../model/types";
import { Drawings } from "./drawings";
import { DiagramList } from "./list";
import { diagramInHash } from "./which";

export function install(studio: Studio): void {
  const { bus, store, canvas, frames } = studio;
  const bannerEl = $<HTMLElement>("#canvas-banner");
  const list = new DiagramList();
  const drawings = new Drawings(studio, list);

  /** A model from the server or an edit: broken by an edit, the last good diagrams stay. */
  const update = (m: ModelView | null, d: Diagnostic[], keepText: string, fromEditor: boolean): void => {
    if (!m && store.model && keepText) {
      // Broken by an edit: keep the last good diagrams, list the problems.
      bus.emit("diagnostics.set", d);
      bannerEl.textContent = keepText;
      bannerEl.hidden = false;
    } else {
      bannerEl.hidden = true;
      drawings.set(m, d, fromEditor);
    }
    frames.schedule();
  };

  bus.on("model.set", (m, d, fromEditor) => drawings.set(m, d, fromEditor));
  bus.on("model.relayout", () => drawings.set(store.model, store.diagnostics));
  bus.on("model.edited", (m, d) =>
    update(
      m,
      d,
      // a folder without a model yet has no last good drawing to keep
      bus.request("edit.empty")
        ? ""
        : "The model does not compile now (see Diagnostics): the diagram shows its last version that did.",
      true,
    ),
  );
  bus.on("server.model", (msg) =>
    update(
      msg.model,
      msg.diagnostics ?? [],
      "The model no longer compiles (see Diagnostics): showing the last version that did.",
      false,
    ),
  );
  bus.on("diagram.select", (id) => drawings.select(id));
  bus.on("session.reset", () => {
    bannerEl.hidden = true;
  });
  bus.on("diagnostics.changed", (d) => list.badges(store.model, d));
  bus.on("frame.render", () => list.pulse(store.live.dirtyLanes, store.laneDiagram));
  window.addEventListener("hashchange", () => {
    const id = diagramInHash(location.hash);
    if (id && id !== canvas.current) drawings.select(id);
  });
}
