// The properties panel (edit mode): the selection's fields as forms. A node: id, fields, flows
// out; a flow: its guard; a swimlane: its name; a component: name, deployment, ports, links; a
// part picked in the library: its name and settings. Each change is an edit sent to the studio.

import { $ } from "../../core/dom";
import type { Studio } from "../../core/studio";
import { componentProps, newComponentProps } from "./component";
import { edgeProps, laneProps } from "./flow";
import { nodeProps } from "./node";
import { Panel } from "./panel";

export function install(studio: Studio): void {
  const { bus, store, canvas } = studio;
  const panel = new Panel(studio, $<HTMLElement>("#props"));
  panel.drawBody = (body, s) => {
    if (s.type === "node") nodeProps(panel, body, s.lane, s.id);
    else if (s.type === "edge") edgeProps(panel, body, s.lane, s.source, s.target);
    else if (s.type === "lane") laneProps(panel, body, s.lane);
    else if (s.type === "component") componentProps(panel, body, s.name);
    else if (s.type === "new-component") newComponentProps(panel, body, s.impl);
  };

  bus.on("props.render", () => {
    if (store.edit) panel.render();
  });
  bus.on("props.focus", (selector, ifEmpty = false) => {
    const input = panel.el.querySelector<HTMLInputElement>(selector);
    if (input && (!ifEmpty || input.value === "")) input.focus();
  });
  // A press elsewhere (the palette, the canvas: they keep the focus where it is) ends the typing
  // in a field of the panel: its text is sent as on Enter, before what the press does — a call
  // typed and then a palette item clicked is not lost.
  window.addEventListener(
    "pointerdown",
    (ev) => {
      const a = document.activeElement;
      if (a instanceof HTMLInputElement && panel.el.contains(a) && !panel.el.contains(ev.target as Node)) a.blur();
    },
    true,
  );
  // a double click on a node, a lane's title or a component: its name, ready to be typed over
  canvas.el.addEventListener("dblclick", (ev) => {
    const t = ev.target as Element;
    if (!t.closest?.("g.node, g.component, .lane-header, .lane-title, .lane-sub")) return;
    const input = panel.el.querySelector<HTMLInputElement>('input[name="rename"]');
    if (!input) return;
    input.focus();
    input.select();
  });
}
