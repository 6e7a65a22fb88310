// What deleting a selection takes with it that the user may not see. Pure (test/selection.test.ts).

import { findLane, type Selection } from "../../core/selection";
import type { ModelView } from "../../model/types";

const plural = (n: number, what: string): string => `${n} ${what}${n === 1 ? "" : "s"}`;

/** The question to ask before deleting `s` from `m`, or null when it takes nothing much with it:
 * a swimlane with nodes (and its file when it is the file's only lane), a component that lanes run
 * on or nodes call (they will no longer check). */
export function lossText(s: NonNullable<Selection>, m: ModelView | null): string | null {
  if (!m) return null;
  if (s.type === "lane") {
    const lane = findLane(m, s.lane);
    if (!lane) return null;
    const n = lane.nodes.filter((x) => x.kind !== "start" && x.kind !== "end").length;
    const alone = m.diagrams.find((d) => d.file === lane.file)?.lanes.length === 1;
    if (!n) return null;
    return `Delete the swimlane ${s.lane} with its ${plural(lane.nodes.length, "node")}${alone ? ` and its file ${lane.file}` : ""}?`;
  }
  if (s.type === "component") {
    const lanes = m.diagrams.flatMap((d) => d.lanes).filter((l) => (l.component ?? l.name) === s.name && !l.virtual);
    let calls = 0;
    for (const d of m.diagrams)
      for (const l of d.lanes)
        for (const x of l.nodes) {
          const text = [
            x.label,
            ...Object.values(x.fields ?? {}).map((v) => (typeof v === "string" ? v : JSON.stringify(v))),
          ].join(" ");
          if (new RegExp(`(^|[^\\w.])${s.name}\\.`).test(text)) calls += 1;
        }
    if (!lanes.length && !calls) return null;
    const parts = [
      lanes.length ? `${plural(lanes.length, "swimlane")} run${lanes.length === 1 ? "s" : ""} on it` : "",
      calls ? `${plural(calls, "node")} call${calls === 1 ? "s" : ""} it` : "",
    ].filter(Boolean);
    return `Delete the component ${s.name}? ${parts.join(" and ")} (${lanes.length && calls ? "they" : lanes.length ? "it" : "they"} will no longer check).`;
  }
  return null;
}
