// The canvas's left and right edges say which swimlanes are off them ("→ 2 more lanes: TurnRight,
// Stop"): a wide diagram opened at a readable zoom is not silently cut. A click (or Enter) pans to
// the next of them; a pan by hand, so following stops.

import { $ } from "../../core/dom";
import type { Studio } from "../../core/studio";
import type { DiagramView } from "../../draw/render";
import { hintText, type Offside, offside, panTo } from "./edges-decide";

export function installEdges({ bus, canvas }: Studio): void {
  const buttons = { left: $<HTMLButtonElement>("#lanes-left"), right: $<HTMLButtonElement>("#lanes-right") };
  let last: Offside = { left: [], right: [] };
  let key = "";

  const update = (v: DiagramView): void => {
    if (v !== canvas.shown() || !v.view) return;
    const { W } = canvas.size();
    const now = `${v.id} ${v.view.x.toFixed(1)} ${v.view.k.toFixed(4)} ${W}`;
    if (now === key) return; // (a vertical pan changes nothing here)
    key = now;
    last = offside(canvas.laneSpans(v), v.view, W);
    for (const side of ["left", "right"] as const) {
      const lanes = last[side];
      const b = buttons[side];
      b.hidden = lanes.length === 0;
      if (!lanes.length) continue;
      const text = `${side === "left" ? "← " : ""}${hintText(lanes)}${side === "right" ? " →" : ""}`;
      b.textContent = text;
      b.title = `Show ${lanes[0].name} (the diagram goes on to the ${side})`;
      b.dataset.lanes = lanes.map((s) => s.name).join(",");
    }
  };

  const go = (side: "left" | "right"): void => {
    const v = canvas.shown();
    const next = last[side][0];
    if (!v?.view || !next) return;
    bus.emit("follow.set", false); // moved by hand: the view stays where the user put it
    v.view.x = panTo(next, v.view, canvas.size().W, side);
    canvas.apply(v, 1);
  };

  for (const side of ["left", "right"] as const) {
    buttons[side].addEventListener("pointerdown", (ev) => ev.stopPropagation()); // not a pan
    buttons[side].addEventListener("click", () => go(side));
  }
  canvas.applied.push(update);
  bus.on("diagram.shown", () => {
    key = "";
    for (const b of Object.values(buttons)) b.hidden = true;
    const v = canvas.shown();
    if (v) update(v);
  });
}
