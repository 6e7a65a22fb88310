// Which diagrams a model has, which one to show, and which problems are a diagram's. Pure
// (test/diagrams.test.ts).

import { sameFile } from "../../model/paths";
import type { Diagnostic, ModelDiagram, ModelView } from "../../model/types";

/** The ids of a model's diagrams, in the list's order: the components first, then the activities. */
export function diagramIds(m: ModelView | null): string[] {
  return m ? ["components", ...m.diagrams.map((d) => d.id)] : [];
}

/** The diagram to show of model `m`: the one the address names, else the one shown, else the first
 * activity (the components when there is none). */
export function firstDiagram(m: ModelView, wanted: string, current: string): string {
  const ids = diagramIds(m);
  if (wanted && ids.includes(wanted)) return wanted;
  if (current && ids.includes(current)) return current;
  return m.diagrams[0]?.id ?? "components";
}

/** The diagram an address's fragment names (`#diagram=<id>`), or "". */
export function diagramInHash(hash: string): string {
  const m = /diagram=([^&]+)/.exec(hash);
  return m ? decodeURIComponent(m[1]) : "";
}

/** The problems in a diagram's files (its own and its lanes'). */
export function problemsIn(d: ModelDiagram, list: Diagnostic[]): Diagnostic[] {
  const files = d.lanes.map((l) => l.file).concat([d.file]);
  return list.filter((x) => files.some((f) => sameFile(f, x.file)));
}
