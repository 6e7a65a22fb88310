// The diagram by keyboard: the canvas and its nodes, swimlane headers and components are focusable
// (draw/render.ts gives them tabindex); Tab walks them and the one focused is panned into view.
// Focus alone selects nothing (Tab passes nodes on its way to the palette or the panel); in edit
// mode space selects the focused element, Enter selects it and goes to its first field
// ("canvas.activate"; after "Connect to…" both connect to it; a node that calls an activity, when
// only watching, opens it), Delete deletes it. Esc in the properties panel comes back to the
// selected element; after an edit redraws the diagram, the focus stays on the selection.

import type { Selection } from "../../core/selection";
import type { Studio } from "../../core/studio";

const FOCUSABLE = "g.node, g.component, g.lane-head";

export function install({ bus, store, canvas }: Studio): void {
  const el = canvas.el;
  el.tabIndex = 0;
  el.setAttribute("aria-label", "diagram: Tab to its nodes; arrows pan, + and - zoom, f fits");
  /** the last input was a key (not the pointer): focus then selects */
  let byKeys = false;
  /** the focus is (or was, until a redraw removed its element) in the canvas */
  let inCanvas = false;
  window.addEventListener(
    "keydown",
    () => {
      byKeys = true;
    },
    true,
  );
  window.addEventListener(
    "pointerdown",
    () => {
      byKeys = false;
    },
    true,
  );
  document.addEventListener("focusin", (ev) => {
    inCanvas = el.contains(ev.target as Node);
  });

  // A press of the pointer on the drawing focuses nothing (as before it was focusable): the keys
  // stay the page's, and Delete deletes the selection, not the node pressed last. (Its pointer
  // events — select, drag, pan, double-click — are not the mouse's default and go on.)
  el.addEventListener("mousedown", (ev) => {
    if ((ev.target as Element).closest?.("svg")) ev.preventDefault();
  });

  el.addEventListener("focusin", (ev) => {
    if (!byKeys) return;
    const t = (ev.target as Element).closest?.(FOCUSABLE);
    const v = canvas.shown();
    if (!t || !byKeys || !v) return;
    if (!t.closest(".lane-head")) canvas.showElement(v, t); // a header sticks to the top itself
    bus.emit("follow.set", false); // moved by hand: the view stays on what has the focus
  });

  /** Select the focused element (no change when it is selected already). */
  const selectFocused = (t: Element): void => {
    const edit = store.edit;
    const sel = selectionOf(t);
    if (!edit || !sel || JSON.stringify(sel) === JSON.stringify(edit.selection)) return;
    edit.selection = sel;
    bus.emit("props.render");
    bus.request("selection.highlight");
  };

  el.addEventListener("keydown", (ev) => {
    if (ev.ctrlKey || ev.metaKey || ev.altKey) return;
    const t = (ev.target as Element).closest?.(FOCUSABLE);
    if (!t) return;
    if (ev.key === "Delete" || ev.key === "Backspace") {
      // what has the focus is what goes (the page's Delete then deletes the selection)
      if (!el.classList.contains("connecting")) selectFocused(t);
      return;
    }
    if (ev.key !== "Enter" && ev.key !== " ") return;
    ev.preventDefault();
    ev.stopPropagation(); // not the page's space (play)
    if (ev.key === " " && store.edit && !el.classList.contains("connecting")) {
      selectFocused(t); // space selects; Enter also goes to its first field
      return;
    }
    if (bus.request("canvas.activate", t)) return;
    // watching only: a node that calls an activity opens it
    const called = t.closest("g.node")?.getAttribute("data-calls");
    const diagram = called ? store.laneDiagram.get(called) : undefined;
    if (diagram) bus.emit("diagram.select", diagram);
  });

  const focusSelection = (): void => {
    const shown = bus.request("selection.highlight");
    const s = store.edit?.selection;
    // a flow is not focusable: its source node is
    const target =
      s?.type === "lane"
        ? laneHead(s.lane)
        : s?.type === "edge"
          ? nodeG(s.lane, s.source)
          : shown?.matches(FOCUSABLE)
            ? shown
            : null;
    ((target ?? el) as Element & HTMLOrSVGElement).focus();
  };
  const nodeG = (lane: string, id: string): Element | null =>
    el.querySelector(
      `svg[data-diagram="${CSS.escape(canvas.current)}"] g.node[data-lane="${CSS.escape(lane)}"][data-node="${CSS.escape(id)}"]`,
    );
  const laneHead = (lane: string): Element | null =>
    el.querySelector(
      `svg[data-diagram="${CSS.escape(canvas.current)}"] g.lane[data-lane="${CSS.escape(lane)}"] g.lane-head`,
    );
  bus.on("canvas.focus-selection", focusSelection);

  // an edit redrew the diagram under the focus: the focus goes to the selection again
  bus.on("selection.marked", (shown) => {
    const a = document.activeElement;
    if (!inCanvas || !shown?.matches(FOCUSABLE) || (a && a !== document.body && a.isConnected)) return;
    (shown as Element & HTMLOrSVGElement).focus({ preventScroll: true });
  });

  // "Connect to…": the focus goes to the node it starts from; Tab to the next one, Enter
  bus.on("connect.start", (lane, id) => {
    if (!byKeys) return; // with the pointer: the next node is clicked
    (nodeG(lane, id) as SVGGElement | null)?.focus({ preventScroll: true });
  });
}

/** What a focused element of the canvas selects. */
function selectionOf(t: Element): Selection {
  const node = t.closest("g.node");
  if (node) return { type: "node", lane: node.getAttribute("data-lane")!, id: node.getAttribute("data-node")! };
  const comp = t.closest("g.component");
  if (comp) return { type: "component", name: comp.getAttribute("data-component")! };
  const lane = t.closest("g.lane")?.getAttribute("data-lane");
  return lane ? { type: "lane", lane } : null;
}
