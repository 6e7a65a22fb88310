// Undo and redo (Ctrl-Z, Ctrl-Shift-Z or Ctrl-Y): the studio keeps the history of the edits; an
// answer is shown as an edit's is.

import { $ } from "../../core/dom";
import type { Studio } from "../../core/studio";
import type { EditAnswer } from "../../model/types";

export function install({ bus, hooks, api }: Studio): void {
  const history = async (which: "undo" | "redo"): Promise<void> => {
    await bus.request("edit.settle");
    hooks.edit!.busy = true;
    const a = await api.request<EditAnswer>(`/api/${which}`, {});
    if (a) bus.emit("edit.apply", a, true);
    hooks.edit!.busy = false;
  };
  $<HTMLButtonElement>("#undo").onclick = () => void history("undo");
  $<HTMLButtonElement>("#redo").onclick = () => void history("redo");
  bus.on("edit.history", (which) => void history(which));
}
