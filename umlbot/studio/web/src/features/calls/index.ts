// The Calls panel: the newest calls first (the view state keeps the last 200), updated in place
// as their answers come.

import { $ } from "../../core/dom";
import type { Studio } from "../../core/studio";
import type { CallRow } from "../../model/state";
import { needsRebuild } from "./order";
import { fillRow, newRow } from "./rows";

interface RowEl {
  tr: HTMLTableRowElement;
  row: CallRow;
}

export function install({ bus, store }: Studio): void {
  const body = $<HTMLTableSectionElement>("#calls tbody");
  let rows = new Map<string, RowEl>();

  const clear = (): void => {
    rows = new Map();
    body.replaceChildren();
  };

  const flush = (full: boolean): void => {
    const newest = store.live.newestCalls();
    if (
      full ||
      needsRebuild(
        newest.map((r) => r.key),
        rows,
      )
    ) {
      rows = new Map();
      const frag = document.createDocumentFragment();
      for (const r of newest) {
        const tr = newRow(r);
        rows.set(r.key, { tr, row: r });
        frag.append(tr);
      }
      body.replaceChildren(frag);
      return;
    }
    const keep = new Set(newest.map((r) => r.key));
    for (const [key, re] of rows) {
      if (!keep.has(key)) {
        re.tr.remove();
        rows.delete(key);
      }
    }
    const frag = document.createDocumentFragment();
    for (const r of newest) {
      const re = rows.get(r.key);
      if (!re) {
        const tr = newRow(r);
        rows.set(r.key, { tr, row: r });
        frag.append(tr);
      } else if (re.row !== r) {
        re.row = r;
        fillRow(re.tr, r);
      }
    }
    body.prepend(frag);
  };

  bus.on("session.reset", clear);
  bus.on("live.reset", clear);
  bus.on("frame.render", (full) => {
    if (store.live.dirtyCalls) flush(full);
  });
}
