// A call's row of the Calls panel: time, component.feature, arguments, result, latency.

import { fmtMs } from "../../draw/render";
import { clockText, jsonText } from "../../model/format";
import type { CallRow } from "../../model/state";

export function fillRow(tr: HTMLTableRowElement, r: CallRow): void {
  const cells = tr.cells;
  cells[0].textContent = clockText(r.time);
  cells[1].replaceChildren(r.component, document.createElement("wbr"), `.${r.feature}`); // may wrap before the dot
  cells[2].textContent = r.args === undefined ? r.detail : jsonText(r.args);
  const res = cells[3];
  if (r.ok === true) {
    res.textContent = r.hasValue ? jsonText(r.value) : "ok";
    res.className = "result ok";
  } else if (r.ok === false) {
    res.textContent = `error: ${r.error || jsonText(r.value)}`;
    res.className = "result err";
  } else {
    res.textContent = "sent…";
    res.className = "result pending";
  }
  cells[4].textContent = r.latencyMs === undefined ? "" : `${fmtMs(r.latencyMs)} ms`;
  for (const c of cells) c.title = c.textContent ?? ""; // a cell cut short: its whole text on hover
}

export function newRow(r: CallRow): HTMLTableRowElement {
  const tr = document.createElement("tr");
  tr.dataset.component = r.component;
  tr.dataset.feature = r.feature;
  for (const cls of ["time", "call", "args", "result", "latency"]) {
    const td = document.createElement("td");
    td.className = cls;
    tr.append(td);
  }
  fillRow(tr, r);
  return tr;
}
