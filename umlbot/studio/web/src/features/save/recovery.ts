// Edits a previous studio kept when it quit unsaved: the user restores or discards them.

import type { Studio } from "../../core/studio";
import type { EditAnswer, EditInfo } from "../../model/types";

export function offerRecovery({ bus, api }: Studio, r: NonNullable<EditInfo["recovery"]>): void {
  const when = r.time ?? "a previous session";
  const what = [...r.files, ...(r.layout ? ["positions"] : [])].join(", ");
  bus.request("notice.show", {
    kind: "recovery",
    text: `The studio quit with unsaved edits (${what}); they were kept, your files are unchanged. Restore them into the page, or discard them for good.`,
    actions: [
      {
        action: "restore",
        label: `Restore the unsaved edits of ${when}`,
        title: "Put the kept edits back into the page (not saved yet: Save writes them)",
        run: async () => {
          const a = await api.request<EditAnswer>("/api/recover", { action: "restore" });
          if (a) {
            bus.emit("edit.apply", a, true);
            bus.request("notice.show", {
              kind: "restored",
              text: `Restored the edits of ${when}: Save writes them, Undo goes back to the files.`,
              hideAfterMs: 8000,
            });
          }
        },
      },
      {
        action: "discard",
        label: "Discard them",
        title: "Delete the kept edits for good; your model files stay as they are",
        run: async () => {
          if (await api.request<EditAnswer>("/api/recover", { action: "discard" })) {
            bus.request("notice.show", {
              kind: "discarded",
              text: "The kept edits were discarded.",
              hideAfterMs: 4000,
            });
          }
        },
      },
    ],
  });
}
