// The selection in edit mode: outlined on the canvas (after every redraw too), dropped when the
// user turns to another diagram that cannot show it, deleted with Delete (asking first when it
// takes more with it than is seen).

import type { Selection } from "../../core/selection";
import type { Studio } from "../../core/studio";
import type { Op } from "../../model/types";
import { lossText } from "./loss";

/** The CSS selector of the drawn element(s) of a selection ("" when it is not drawn). */
function selectionQuery(s: NonNullable<Selection>): string {
  const q = CSS.escape;
  if (s.type === "node") return `g.node[data-lane="${q(s.lane)}"][data-node="${q(s.id)}"]`;
  if (s.type === "edge") {
    return `g.edge[data-lane="${q(s.lane)}"][data-source="${q(s.source)}"][data-target="${q(s.target)}"]`;
  }
  if (s.type === "component") return `g.component[data-component="${q(s.name)}"]`;
  if (s.type === "lane") return `g.lane[data-lane="${q(s.lane)}"]`;
  return "";
}

/** The operation that deletes a selection. */
function removal(s: NonNullable<Selection>): Op | null {
  if (s.type === "node") return { op: "remove_node", lane: s.lane, id: s.id };
  if (s.type === "edge") return { op: "disconnect", lane: s.lane, source: s.source, target: s.target };
  if (s.type === "component") return { op: "remove_component", name: s.name };
  if (s.type === "lane") return { op: "remove_lane", lane: s.lane };
  return null;
}

export function install({ bus, store, canvas }: Studio): void {
  /** Outline the selected node/edge/component/lane; the selected element of the shown diagram. */
  const highlight = (): Element | null | undefined => {
    const edit = store.edit;
    if (!edit) return undefined;
    for (const e of canvas.el.querySelectorAll(".selected")) e.classList.remove("selected");
    const s = edit.selection;
    if (!s) {
      bus.emit("selection.marked", null);
      return null;
    }
    const q = selectionQuery(s);
    let shown: Element | null = null;
    if (q) {
      for (const e of canvas.el.querySelectorAll(q)) {
        e.classList.add("selected");
        if (e.closest("svg")?.getAttribute("data-diagram") === canvas.current) shown = e;
      }
    }
    const found = s.type === "lane" ? null : shown;
    bus.emit("selection.marked", s.type === "lane" ? laneHead(s.lane) : found);
    return found;
  };
  const laneHead = (lane: string): Element | null =>
    canvas.el.querySelector(
      `svg[data-diagram="${CSS.escape(canvas.current)}"] g.lane[data-lane="${CSS.escape(lane)}"] g.lane-head`,
    );

  const remove = async (confirmed = false): Promise<void> => {
    const edit = store.edit!;
    const s = edit.selection;
    if (!s) return;
    const loss = confirmed ? null : lossText(s, store.model);
    if (loss) {
      const what = JSON.stringify(s);
      bus.request("notice.show", {
        kind: "confirm",
        text: loss,
        actions: [
          {
            action: "confirm",
            label: "Delete",
            run: async () => {
              bus.emit("notice.hide");
              if (JSON.stringify(edit.selection) === what) await remove(true);
            },
          },
          { action: "cancel", label: "Keep it", run: () => bus.emit("notice.hide") },
        ],
      });
      return;
    }
    const op = removal(s);
    if (op && (await bus.request("edit.send", [op]))) {
      edit.selection = null;
      bus.emit("props.render");
    }
  };

  bus.on("selection.highlight", highlight);
  bus.on("selection.delete", () => void remove());
  bus.on("diagram.shown", () => {
    const edit = store.edit;
    if (!edit) return;
    if (edit.selection?.type === "new-component" && canvas.current !== "components") edit.selection = null;
    bus.emit("palette.render");
    bus.emit("props.render");
  });
}
