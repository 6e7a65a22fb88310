// The studio's HTTP API in edit mode (docs/studio.md, "Editing requests"): a POST with the
// session's token; a failure is said where it belongs (at the form's fields, as a conflict with
// the disk, or in the notice bar) and the caller gets null.

import type { Bus } from "./events";
import { markFieldErrors } from "./forms";
import type { StudioHooks } from "./hooks";
import type { Store } from "./store";

interface Failed {
  error?: string;
  message?: string;
  fields?: Record<string, string>;
  conflict?: string[];
}

export class Api {
  constructor(
    private bus: Bus,
    private store: Store,
    private hooks: StudioHooks,
  ) {}

  /** POST `body` to `path` with the token; null (and a notice, unless `quiet`) when it failed. A
   * problem with a field of `form` (`data-field`) is shown at that field. */
  async request<T>(path: string, body: Record<string, unknown>, quiet = false, form?: HTMLElement): Promise<T | null> {
    const bus = this.bus;
    if (this.hooks.edit) this.hooks.edit.requests += 1;
    try {
      const res = await fetch(path, {
        method: "POST",
        headers: { "Content-Type": "application/json" },
        body: JSON.stringify({ token: this.store.edit?.info.token, ...body }),
      });
      const text = await res.text();
      let data: unknown = null;
      try {
        data = text ? JSON.parse(text) : null;
      } catch {
        data = { error: text };
      }
      const failed = data as Failed | null;
      if (res.status === 409 && /^\/api\/(undo|redo)$/.test(path)) {
        bus.request("notice.show", {
          kind: "hint",
          text: failed?.error ?? `nothing to ${path.slice(5)}`,
          hideAfterMs: 3000,
        });
        return null;
      }
      if (!res.ok) {
        const err = failed?.message ?? failed?.error ?? `${res.status} ${res.statusText}`;
        if (quiet) return null;
        if (form && failed?.fields && markFieldErrors(form, failed.fields)) {
          // said at the field(s) it is about; a notice of an earlier problem is stale now
          bus.emit("notice.hide", "error");
        } else if (res.status === 409 && failed?.conflict) {
          bus.emit("conflict.show", failed.conflict);
        } else if (res.status === 409 && path === "/api/edit") {
          // another window edited meanwhile: take the server's state (a fresh hello) and say so
          bus.request("notice.show", {
            kind: "error",
            text: `${err} — the page takes the server's current model.`,
            hideAfterMs: 8000,
          });
          bus.emit("session.resync");
        } else bus.request("notice.show", { kind: "error", text: err });
        this.hooks.edit?.errors.push(err);
        return null;
      }
      if (!quiet) bus.emit("notice.hide", "error"); // it worked: an error shown before is over
      return data as T;
    } catch (exc) {
      if (quiet) return null;
      bus.request("notice.show", { kind: "error", text: `The studio server did not answer: ${String(exc)}` });
      return null;
    }
  }
}
