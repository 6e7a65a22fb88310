// Save and conflicts: Save (Ctrl-S) writes the edits to the model files; a file changed on disk
// is reloaded when the page has no unsaved edits, else the user decides (reload or keep mine);
// unsaved edits a previous studio kept when it quit are offered back (restore or discard).

import { $ } from "../../core/dom";
import type { Studio } from "../../core/studio";
import type { EditAnswer } from "../../model/types";
import { offerRecovery } from "./recovery";

export function install(studio: Studio): void {
  const { bus, store, hooks, api, frames } = studio;
  const saveBtn = $<HTMLButtonElement>("#save");
  /** the user kept their edits over a file changed on disk: Save replaces it */
  let force = false;

  const setDirty = (dirty: boolean): void => {
    hooks.edit!.dirty = dirty;
    saveBtn.dataset.dirty = String(dirty);
    saveBtn.textContent = dirty ? "Save •" : "Saved";
    saveBtn.title = dirty ? "Write the edits to the model files (Ctrl-S)" : "Nothing to save";
    document.title = document.title.replace(/^• /, "");
    if (dirty) document.title = `• ${document.title}`;
  };

  const save = async (): Promise<void> => {
    await bus.request("edit.settle");
    const a = await api.request<{ saved: string[]; dirty: boolean; version?: number }>("/api/save", {
      version: hooks.edit!.version,
      force,
    });
    if (!a) return;
    force = false;
    if (a.version !== undefined) hooks.edit!.version = a.version;
    setDirty(a.dirty);
    bus.request("notice.show", {
      kind: "saved",
      text: a.saved.length ? `Saved ${a.saved.join(", ")}` : "Nothing changed: no file written",
      hideAfterMs: 3000,
    });
  };

  /** A file changed on disk while the page has unsaved edits: nothing was overwritten. */
  const showConflict = (changed: string[]): void => {
    bus.request("notice.show", {
      kind: "conflict",
      text: `${changed.join(", ")} changed on disk while you have unsaved edits. Nothing was overwritten.`,
      files: changed,
      actions: [
        {
          action: "reload",
          label: "Reload from disk (discard my edits)",
          run: async () => {
            const a = await api.request<EditAnswer>("/api/reload", {});
            if (a) {
              force = false;
              bus.emit("edit.apply", a, true);
              bus.request("notice.show", {
                kind: "reloaded",
                text: "Reloaded from disk: your unsaved edits were discarded.",
                hideAfterMs: 6000,
              });
            }
          },
        },
        {
          action: "keep",
          label: "Keep mine",
          run: () => {
            force = true;
            bus.request("notice.show", {
              kind: "kept",
              text: `Your edits are kept; Save will replace ${changed.join(", ")} on disk.`,
              hideAfterMs: 8000,
            });
          },
        },
      ],
    });
  };

  saveBtn.onclick = () => void save();
  bus.on("edit.dirty", setDirty);
  bus.on("edit.save", () => void save());
  bus.on("conflict.show", showConflict);
  bus.on("server.conflict", (msg) => {
    if (!store.edit) return;
    if (msg.version !== undefined) hooks.edit!.version = msg.version;
    showConflict(msg.changed);
  });
  // A file changed on disk while the page was clean: the server reloaded it.
  bus.on("server.files", (msg) => {
    if (store.edit) {
      const answer: EditAnswer = {
        version: msg.version,
        model: msg.model,
        diagnostics: msg.diagnostics ?? [],
        lane_files: msg.lane_files,
        dirty: msg.dirty ?? false,
        layout: msg.layout,
      };
      bus.emit("edit.apply", answer, true);
      const was = msg.changed.length === 1 ? "was" : "were";
      bus.request("notice.show", {
        kind: "reloaded",
        text: `${msg.changed.join(", ")} ${was} changed on disk: reloaded.`,
        hideAfterMs: 8000,
      });
    }
    frames.schedule();
  });
  // a conflict or kept edits wait for the user's decision (a run's notice never hides them)
  bus.on("edit.after-hello", (info) => {
    if (info.conflict?.length) showConflict(info.conflict);
    else if (info.recovery) offerRecovery(studio, info.recovery);
  });
}
