// The palette (edit mode): on an activity diagram the node kinds and the swimlane form, on the
// components diagram (or with no model) the component library.

import { $ } from "../../core/dom";
import type { Studio } from "../../core/studio";
import { drawLibrary } from "./library";
import { drawNodes, type LaneFileChoice } from "./nodes";

export function install(studio: Studio): void {
  const { bus, store, canvas } = studio;
  const p = $<HTMLElement>("#palette");
  const choice: LaneFileChoice = { file: "" };

  const render = (): void => {
    if (!store.edit) return;
    p.replaceChildren();
    const m = store.model;
    if (canvas.current === "components" || !m) drawLibrary(studio, p);
    else drawNodes(studio, p, m, choice);
  };

  bus.on("palette.render", render);
  bus.on("model.missing", render);
}
