// Edits go to the studio one request at a time, each with the version it edits (the server refuses
// a stale one); the answers are applied in order.

import { clearFieldErrors } from "../../core/forms";
import type { Studio } from "../../core/studio";
import type { EditAnswer, Op } from "../../model/types";

const TIMINGS_KEPT = 200;

interface Queued {
  ops: Op[];
  resolve: (ok: boolean) => void;
  form?: HTMLElement;
}

export class EditQueue {
  private queue: Queued[] = [];

  constructor(private studio: Studio) {}

  /** Apply operations; true when the server applied them. A problem with a field of `form`
   * (`data-field`) is shown at that field. */
  send(ops: Op[], form?: HTMLElement): Promise<boolean> {
    if (form) clearFieldErrors(form);
    return new Promise((resolve) => {
      this.queue.push({ ops, resolve, form });
      if (this.queue.length === 1) void this.pump();
    });
  }

  /** Wait until every queued edit is answered. */
  async settle(): Promise<void> {
    if (!this.queue.length) return;
    await new Promise<void>((resolve) => {
      this.queue.push({ ops: [], resolve: () => resolve() });
    });
  }

  private async pump(): Promise<void> {
    const { bus, api } = this.studio;
    const hooks = this.studio.hooks.edit!;
    hooks.busy = true;
    while (this.queue.length) {
      const { ops, resolve, form } = this.queue[0];
      const sent = performance.now();
      const a = await api.request<EditAnswer>("/api/edit", { version: hooks.version, ops }, false, form);
      if (a) {
        const timings = hooks.timings;
        timings.push({ version: a.version, sent, answered: performance.now() });
        if (timings.length > TIMINGS_KEPT) timings.shift();
        // only positions changed: the page drew them already
        bus.emit("edit.apply", a, !ops.every((o) => o.op === "set_layout"));
      }
      this.queue.shift();
      resolve(!!a);
    }
    hooks.busy = false;
  }
}
