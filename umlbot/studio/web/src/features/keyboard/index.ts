// The page's keys (keymap.ts): in edit mode the editor's first (save, undo/redo, Esc, delete),
// then the viewer's: space plays or pauses a replay, f fits the diagram, l follows the robot.

import type { Studio } from "../../core/studio";
import { editAction, type KeyPress, viewAction } from "./keymap";

export function install({ bus, store }: Studio): void {
  window.addEventListener("keydown", (ev) => {
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
  });
}
