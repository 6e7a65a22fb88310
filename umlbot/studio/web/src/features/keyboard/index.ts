// The page's keys (keymap.ts): in edit mode the editor's first (save, undo/redo, Esc, delete),
// then the viewer's: space plays or pauses a replay, f fits the diagram, l follows the robot, + and
// - zoom, the arrows pan; Esc in the properties panel goes back to the diagram. The diagram's own
// elements by keyboard: canvas.ts. The keys are listed in docs/studio.md ("Keys").

import type { Studio } from "../../core/studio";
import { install as installCanvas } from "./canvas";
import { editAction, type KeyPress, viewAction } from "./keymap";

const PAN_PX = 80;
const ZOOM_STEP = 1.25;

export function install(studio: Studio): void {
  const { bus, store } = studio;
  installCanvas(studio);
  window.addEventListener("keydown", (ev) => {
    if (ev.key === "Escape" && !ev.defaultPrevented && (ev.target as Element).closest?.("#props")) {
      // leaving a field of the properties panel (a completion list open took the Esc first)
      bus.emit("canvas.focus-selection");
      return;
    }
    const t = ev.target as HTMLElement;
    const press: KeyPress = {
      key: ev.key,
      ctrl: ev.ctrlKey,
      meta: ev.metaKey,
      alt: ev.altKey,
      shift: ev.shiftKey,
      tag: t.tagName,
      untouchedInput: t instanceof HTMLInputElement && t.value === t.defaultValue,
    };
    const edit = store.edit;
    // no model yet: nothing to save, undo or delete
    const action = edit && !edit.info.empty ? editAction(press, edit.selection !== null) : null;
    if (action === "save") {
      ev.preventDefault();
      if (/^(INPUT|SELECT|TEXTAREA)$/.test(t.tagName)) t.blur();
      bus.emit("edit.save");
    } else if (action === "undo" || action === "redo") {
      ev.preventDefault();
      bus.emit("edit.history", action);
    } else if (action === "cancel") bus.emit("connect.cancel");
    else if (action === "delete") {
      ev.preventDefault();
      bus.emit("selection.delete");
    }
    if (action) return;
    const view = viewAction(press);
    if (view === "play") {
      if (bus.request("replay.toggle")) ev.preventDefault();
    } else if (view === "fit") bus.emit("view.fit");
    else if (view === "follow") bus.emit("follow.toggle");
    else if (view === "zoom-in" || view === "zoom-out")
      bus.emit("view.zoom", view === "zoom-in" ? ZOOM_STEP : 1 / ZOOM_STEP);
    else if (view) {
      ev.preventDefault();
      const d = { "pan-left": [PAN_PX, 0], "pan-right": [-PAN_PX, 0], "pan-up": [0, PAN_PX], "pan-down": [0, -PAN_PX] }[
        view
      ];
      bus.emit("view.pan", d[0], d[1]);
    }
  });
}
