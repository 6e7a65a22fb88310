// The sidebar's list of diagrams: one entry per diagram, the shown one marked, a badge with the
// count of its problems, a dot that pulses when its lanes run.

import { $ } from "../../core/dom";
import type { Diagnostic, ModelView } from "../../model/types";
import { diagramIds, problemsIn } from "./which";

const PULSE_EVERY_MS = 300;

export class DiagramList {
  private el = $<HTMLUListElement>("#diagram-list");
  private pulsedAt = new Map<string, number>();

  /** An entry per diagram of `m`; a click on one calls `select` with its id. */
  build(m: ModelView | null, select: (id: string) => void): void {
    this.el.replaceChildren();
    for (const id of diagramIds(m)) {
      const li = document.createElement("li");
      li.dataset.diagram = id;
      const d = m?.diagrams.find((x) => x.id === id);
      li.textContent = d ? d.title : "Components";
      const sub = document.createElement("small");
      sub.textContent = d
        ? `${d.lanes.length} lane${d.lanes.length === 1 ? "" : "s"} · ${d.file}`
        : `${m?.components.length ?? 0} components`;
      li.append(sub);
      const dot = document.createElement("i");
      dot.className = "pulse";
      dot.title = "ran just now";
      li.prepend(dot);
      li.addEventListener("click", () => select(id));
      // by keyboard: Tab to it, Enter or space shows it
      li.tabIndex = 0;
      li.addEventListener("keydown", (ev) => {
        if (ev.key !== "Enter" && ev.key !== " ") return;
        ev.preventDefault();
        ev.stopPropagation();
        select(id);
      });
      this.el.append(li);
    }
  }

  markSelected(id: string): void {
    for (const li of this.el.querySelectorAll<HTMLLIElement>("li")) {
      li.classList.toggle("selected", li.dataset.diagram === id);
      if (li.dataset.diagram === id) li.setAttribute("aria-current", "true");
      else li.removeAttribute("aria-current");
    }
  }

  /** Problems per diagram, as a badge in the list. */
  badges(m: ModelView | null, list: Diagnostic[]): void {
    for (const li of this.el.querySelectorAll<HTMLLIElement>("li")) {
      li.querySelector(".badge")?.remove();
      const d = m?.diagrams.find((x) => x.id === li.dataset.diagram);
      if (!d) continue;
      const mine = problemsIn(d, list);
      if (!mine.length) continue;
      const badge = document.createElement("span");
      badge.className = `badge ${mine.some((x) => x.severity === "error") ? "error" : "warning"}`;
      badge.textContent = String(mine.length);
      badge.title = `${mine.length} problem${mine.length === 1 ? "" : "s"} in this diagram`;
      li.querySelector("small")?.before(badge);
    }
  }

  /** Pulse the entry of each diagram whose lanes ran (at most every PULSE_EVERY_MS per diagram). */
  pulse(lanesRan: Set<string>, laneDiagram: Map<string, string>): void {
    if (!lanesRan.size) return;
    const now = performance.now();
    const seen = new Set<string>();
    for (const lane of lanesRan) {
      const id = laneDiagram.get(lane);
      if (!id || seen.has(id)) continue;
      seen.add(id);
      if (now - (this.pulsedAt.get(id) ?? -1e9) < PULSE_EVERY_MS) continue;
      this.pulsedAt.set(id, now);
      const dot = this.el.querySelector<HTMLElement>(`li[data-diagram="${CSS.escape(id)}"] .pulse`);
      dot?.animate([{ opacity: 1 }, { opacity: 0 }], { duration: 1500, fill: "forwards" });
    }
  }
}
