// umlbot studio page: connection, diagram list, live/replay driving, panels.

import { layoutActivity, layoutComponents, warmUp } from "./draw/layout";
import type { DiagramView } from "./draw/render";
import { fmtMs, Renderer } from "./draw/render";
import type { EditHooks } from "./edit";
import { Editor } from "./edit";
import { sameFile } from "./model/paths";
import type { CallRow, Snapshot } from "./model/state";
import { ModelIndex, nodeKey, StudioState } from "./model/state";
import type { Diagnostic, HelloMsg, ModelView, MonitorEvent, ServerMsg } from "./model/types";
import { SimPanel } from "./sim";

interface StudioHooks {
  latencies: number[];
  frames: number[];
  ready: boolean;
  applied: number;
  edit: EditHooks | null;
  follow: boolean; // the view follows the running robot (docs/studio.md, "Follow")
  followPans: number; // pans follow made (tests)
  hellos: number; // hellos received: the first, and one per reconnection (tests)
  durationCounters: () => number; // counters the nodes' duration histograms hold (memory; tests)
  reveal: (lane: string, node: string) => void; // centre a node (tests and docs screenshots)
}
declare global {
  interface Window {
    __studio: StudioHooks;
  }
}
const hooks: StudioHooks = {
  latencies: [],
  frames: [],
  ready: false,
  applied: 0,
  edit: null,
  follow: false,
  followPans: 0,
  hellos: 0,
  durationCounters: () => {
    let n = 0;
    for (const s of state.nodes.values()) n += s.durs.buckets;
    return n;
  },
  reveal: (lane, node) => reveal(lane, node),
};
window.__studio = hooks;
const KEEP = 10_000;
const pushCapped = (a: number[], v: number): void => {
  a.push(v);
  if (a.length > KEEP) a.splice(0, a.length - KEEP);
};

const $ = <T extends HTMLElement>(sel: string): T => document.querySelector(sel) as T;
const canvas = $<HTMLDivElement>("#canvas");
const listEl = $<HTMLUListElement>("#diagram-list");
const titleEl = $<HTMLElement>("#title");
const modeEl = $<HTMLElement>("#mode");
const orchEl = $<HTMLElement>("#orchestrator-status");
const connEl = $<HTMLElement>("#connection");
const gapsEl = $<HTMLElement>("#gaps");
const diagEl = $<HTMLUListElement>("#diagnostics");
const callsBody = $<HTMLTableSectionElement>("#calls tbody");
const brokerEl = $<HTMLElement>("#broker-status");
const replayNotesEl = $<HTMLElement>("#replay-notes");
const replayEl = $<HTMLElement>("#replay");
const playBtn = $<HTMLButtonElement>("#replay-play");
const speedSel = $<HTMLSelectElement>("#replay-speed");
const timeInput = $<HTMLInputElement>("#replay-time");
const clockEl = $<HTMLElement>("#replay-clock");
const messageEl = $<HTMLElement>("#canvas-message");
const bannerEl = $<HTMLElement>("#canvas-banner");
const sim = new SimPanel($<HTMLElement>("#sim"));

// The canvas's size, kept up to date by a ResizeObserver: reading clientWidth after the drawing
// changed would force the browser to lay out the whole diagram there and then.
let canvasW = 0;
let canvasH = 0;
new ResizeObserver(() => {
  canvasW = canvas.clientWidth;
  canvasH = canvas.clientHeight;
}).observe(canvas);
function canvasSize(): { W: number; H: number } {
  if (!canvasW) {
    canvasW = canvas.clientWidth;
    canvasH = canvas.clientHeight;
  }
  return { W: canvasW || 800, H: canvasH || 600 };
}

const renderer = new Renderer();
let model: ModelView | null = null;
let index = new ModelIndex(null);
let state = new StudioState(index);
let mode: "live" | "replay" = "live";
let views = new Map<string, DiagramView>();
let current = "";
let generation = 0;
let laneDiagram = new Map<string, string>();
let replaced = new Map<string, DiagramView>(); // drawings shown until their redraw is ready
let editor: Editor | null = null;
let robotName = "";
let drawnVersion = -1;
const savedViews = new Map<string, { x: number; y: number; k: number }>(); // pan/zoom kept across redraws

// ---------------------------------------------------------------- model and diagrams

function diagramIds(m: ModelView | null): string[] {
  return m ? ["components", ...m.diagrams.map((d) => d.id)] : [];
}

/** Show model `m`; `fromEditor`: the editor's own answer (it draws its panels itself after). */
function setModel(m: ModelView | null, diagnostics: Diagnostic[], fromEditor = false): void {
  drawnVersion = hooks.edit?.version ?? -1;
  generation += 1;
  const gen = generation;
  model = m;
  index = new ModelIndex(m);
  state.index = index;
  renderer.reset(m);
  // The old drawings stay on screen until their new ones are ready (an edit redraws in place).
  for (const v of views.values()) if (v.view) savedViews.set(v.id, v.view);
  for (const [id, v] of views) {
    // a drawing that was itself waiting for its redraw is dropped for the newer one
    replaced.get(id)?.svg.remove();
    replaced.set(id, v);
  }
  views = new Map();
  laneDiagram = new Map();
  for (const d of m?.diagrams ?? []) for (const l of d.lanes) laneDiagram.set(l.name, d.id);

  // Diagram list
  listEl.replaceChildren();
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
    listEl.append(li);
  }
  setDiagnostics(diagnostics);

  if (!m) {
    for (const v of replaced.values()) v.svg.remove();
    replaced = new Map();
    messageEl.textContent = "The model does not compile: see the diagnostics.";
    if (editor?.info.empty) editor.showEmpty(messageEl);
    messageEl.hidden = false;
    editor?.renderPalette();
    hooks.ready = true;
    return;
  }
  messageEl.hidden = true;
  titleEl.textContent = `${m.name} · robot ${robotName}`;
  for (const [id, v] of replaced) {
    if (!diagramIds(m).includes(id)) {
      v.svg.remove();
      replaced.delete(id);
    }
  }
  const wanted = hashDiagram();
  const ids = diagramIds(m);
  const first =
    wanted && ids.includes(wanted)
      ? wanted
      : current && ids.includes(current)
        ? current
        : (m.diagrams[0]?.id ?? "components");
  const was = current;
  current = "";
  select(first, !(fromEditor && first === was));
  void layoutAll(m, first, gen);
}

async function layoutAll(m: ModelView, first: string, gen: number): Promise<void> {
  const order = [first, ...diagramIds(m).filter((id) => id !== first)];
  for (const id of order) {
    try {
      const t0 = performance.now();
      let view: DiagramView | null;
      let t1: number;
      const positions = editor?.positions(id) ?? {};
      if (id === "components") {
        const layout = await layoutComponents(m, positions);
        if (gen !== generation) return;
        t1 = performance.now();
        view = renderer.buildComponents(layout, m);
      } else {
        const d = m.diagrams.find((x) => x.id === id)!;
        const layout = await layoutActivity(d, positions);
        if (gen !== generation) return;
        t1 = performance.now();
        view = await renderer.buildActivity(layout, () => gen !== generation, replaced.get(id));
        if (!view || gen !== generation) return;
      }
      view.svg.style.display = id === current ? "" : "none";
      const was = replaced.get(id);
      if (was && was.svg !== view.svg) was.svg.remove();
      if (view.svg.parentNode !== canvas) canvas.append(view.svg);
      replaced.delete(id);
      views.set(id, view);
      const saved = savedViews.get(id);
      if (saved) {
        view.view = { ...saved };
        if (editor) keepInView(view);
        applyView(view);
      } else if (id === current) fit(view);
      if (id === current) followDue = true; // drawn: where is the robot?
      renderer.adoptFresh(state);
      const sel = editor?.highlightSelection();
      if (sel && id === current) showElement(view, sel);
      if (hooks.edit && id === current) hooks.edit.drawn = drawnVersion;
      state.dirtyOrch = true;
      schedule();
      console.debug(
        `studio: ${id} laid out in ${(t1 - t0).toFixed(0)} ms, drawn in ${(performance.now() - t1).toFixed(0)} ms`,
      );
      if (id === first) {
        // ready once the frame that first paints it is over
        requestAnimationFrame(() =>
          requestAnimationFrame(() => {
            hooks.ready = true;
          }),
        );
      }
    } catch (err) {
      console.error(`studio: layout of ${id} failed`, err);
      if (id === first) hooks.ready = true;
    }
  }
}

function select(id: string, tellEditor = true): void {
  if (!diagramIds(model).includes(id)) return;
  current = id;
  for (const li of listEl.querySelectorAll<HTMLLIElement>("li"))
    li.classList.toggle("selected", li.dataset.diagram === id);
  for (const [vid, v] of views) v.svg.style.display = vid === id ? "" : "none";
  for (const [vid, v] of replaced) v.svg.style.display = vid === id ? "" : "none";
  if (tellEditor) editor?.diagramShown(id);
  const v = views.get(id);
  if (v && !v.view) fit(v);
  followDue = true; // another diagram: its node that ran last, at once
  if (hashDiagram() !== id) history.replaceState(null, "", `#diagram=${encodeURIComponent(id)}`);
}

function hashDiagram(): string {
  const m = /diagram=([^&]+)/.exec(location.hash);
  return m ? decodeURIComponent(m[1]) : "";
}
window.addEventListener("hashchange", () => {
  const id = hashDiagram();
  if (id && id !== current) select(id);
});

let diagnostics: Diagnostic[] = [];
function setDiagnostics(list: Diagnostic[]): void {
  diagnostics = list;
  diagEl.replaceChildren();
  const before = new Map(renderer.marks);
  renderer.marks.clear();
  for (const d of list) {
    const li = document.createElement("li");
    li.className = d.severity;
    li.textContent = d.text;
    diagEl.append(li);
    const at = d.lane !== undefined ? nodeNamed(d.lane ?? "", d.node ?? "") : nodeAtLine(d.file, d.line);
    if (at) {
      const key = nodeKey(at.lane, at.node);
      const old = renderer.marks.get(key);
      if (!old || (old.level === "warning" && d.severity === "error"))
        renderer.marks.set(key, { level: d.severity, message: d.text });
      li.dataset.diagram = at.diagram;
      li.dataset.lane = at.lane;
      li.dataset.node = at.node;
    } else if (d.lane && laneDiagram.has(d.lane)) {
      li.dataset.diagram = laneDiagram.get(d.lane)!; // a problem of the lane itself: its diagram
    }
    li.addEventListener("click", () => {
      if (!li.dataset.diagram) return;
      select(li.dataset.diagram);
      if (li.dataset.lane && li.dataset.node) reveal(li.dataset.lane, li.dataset.node);
    });
  }
  $<HTMLElement>("#diagnostics-count").textContent = String(list.length);
  // Problems per diagram, as a badge in the list.
  for (const li of listEl.querySelectorAll<HTMLLIElement>("li")) {
    li.querySelector(".badge")?.remove();
    const d = model?.diagrams.find((x) => x.id === li.dataset.diagram);
    if (!d) continue;
    const files = d.lanes.map((l) => l.file).concat([d.file]);
    const mine = list.filter((x) => files.some((f) => sameFile(f, x.file)));
    if (!mine.length) continue;
    const badge = document.createElement("span");
    badge.className = `badge ${mine.some((x) => x.severity === "error") ? "error" : "warning"}`;
    badge.textContent = String(mine.length);
    badge.title = `${mine.length} problem${mine.length === 1 ? "" : "s"} in this diagram`;
    li.querySelector("small")?.before(badge);
  }
  // only the nodes whose mark came, went or changed are drawn again (not every node)
  for (const [key, mark] of renderer.marks) {
    const old = before.get(key);
    if (!old || old.level !== mark.level || old.message !== mark.message) state.dirtyNodes.add(key);
  }
  for (const key of before.keys()) if (!renderer.marks.has(key)) state.dirtyNodes.add(key);
}

/** The diagram of a node the server named (null when it is not drawn). */
function nodeNamed(lane: string, node: string): { diagram: string; lane: string; node: string } | null {
  const diagram = laneDiagram.get(lane);
  if (!diagram || !node) return null;
  return index.lanes.get(lane)?.nodes.has(node) ? { diagram, lane, node } : null;
}

/**
 * The node a diagnostic at file:line belongs to: the node of that file whose first line is the last
 * one at or before it (a bad guard on a branch's line marks its decision).
 */
function nodeAtLine(file: string, line: number): { diagram: string; lane: string; node: string } | null {
  let best: { diagram: string; lane: string; node: string; line: number } | null = null;
  for (const dg of model?.diagrams ?? []) {
    for (const lane of dg.lanes) {
      if (!sameFile(lane.file, file)) continue;
      for (const n of lane.nodes) {
        if (n.line <= line && (!best || n.line > best.line))
          best = { diagram: dg.id, lane: lane.name, node: n.id, line: n.line };
      }
    }
  }
  return best;
}

// ---------------------------------------------------------------- pan / zoom

/** Show `v` at its view; `newLanes`: how many lanes not drawn so far it may draw now (the
 * others on the next frames: `cullPending`). */
function applyView(v: DiagramView, newLanes = Infinity): void {
  if (!v.view) return;
  v.viewport.setAttribute("transform", `translate(${v.view.x},${v.view.y}) scale(${v.view.k})`);
  // Level of detail: text too small to read is not drawn (keeps big diagrams fast).
  const k = v.view.k;
  v.svg.classList.toggle("lod-mid", k < LOD_MID);
  v.svg.classList.toggle("lod-far", k < LOD_FAR);
  cullPending = cullLanes(v, newLanes) ? v : null;
  stickLaneHeads(v);
}
/** A view whose lanes are still to be drawn, one a frame (after a follow jump). */
let cullPending: DiagramView | null = null;

// Swimlanes wholly outside the canvas are not drawn (display: none): at a readable zoom a big
// diagram shows a few lanes, and the live updates of the others then cost no layout or paint.
const laneSpan = new WeakMap<Element, LaneSpan>();
interface LaneSpan {
  t: string;
  x: number;
  y: number;
  w: number;
  bodyY: number;
  bg: Element | null;
  head: Element | null;
  texts: Element[];
  tw: number;
  headH: number;
}
/** A lane's place (diagram units) from its attributes: no layout. */
function spanOf(g: Element): LaneSpan {
  const t = g.getAttribute("transform") ?? "";
  let span = laneSpan.get(g);
  if (!span || span.t !== t) {
    const m = /translate\(([-\d.e]+)[ ,]+([-\d.e]+)/.exec(t);
    const body = /translate\([-\d.e]+[ ,]+([-\d.e]+)/.exec(
      g.querySelector(".lane-body")?.getAttribute("transform") ?? "",
    );
    const bg = g.querySelector(".lane-bg");
    const head = g.querySelector(".lane-head");
    span = {
      t,
      x: m ? Number(m[1]) : 0,
      y: m ? Number(m[2]) : 0,
      w: Number(bg?.getAttribute("width") ?? 0),
      bodyY: body ? Number(body[1]) : 0,
      bg,
      head,
      texts: head ? [...head.querySelectorAll("text")] : [],
      tw: Number(head?.getAttribute("data-tw") ?? 0),
      headH: Number(head?.getAttribute("data-h") ?? 0),
    };
    laneSpan.set(g, span);
  }
  return span;
}

/** A node's box in diagram units, from its data attributes and its lane's (no layout); null for
 * anything else. */
function nodeBox(el: Element): { x: number; y: number; w: number; h: number } | null {
  const lane = el.matches("g.node") ? el.closest("g.lane") : null;
  if (!lane) return null;
  const span = spanOf(lane);
  const num = (a: string): number => Number(el.getAttribute(a) ?? 0);
  return { x: span.x + num("data-x"), y: span.y + span.bodyY + num("data-y"), w: num("data-w"), h: num("data-h") };
}
function cullLanes(v: DiagramView, newLanes = Infinity): boolean {
  if (!v.view) return false;
  const { W } = canvasSize();
  const margin = 200;
  const show: { g: Element; off: number }[] = [];
  for (const g of v.viewport.children) {
    if (!g.classList.contains("lane")) continue;
    const span = spanOf(g);
    const left = v.view.x + span.x * v.view.k;
    const right = left + span.w * v.view.k;
    const out = right < -margin || left > W + margin;
    if (out) g.classList.add("culled");
    else if (g.classList.contains("culled")) show.push({ g, off: Math.abs((left + right) / 2 - W / 2) });
  }
  // a lane drawn again is laid out anew (all its nodes): the one nearest the middle first
  if (show.length > newLanes) show.sort((a, b) => a.off - b.off);
  for (const { g } of show.slice(0, newLanes)) g.classList.remove("culled");
  return show.length > newLanes;
}

// Each lane's header stays on the lane's visible part: at the top of the canvas while the lane goes
// on below it, its name centred on the part of the lane the canvas shows (a lane wider than the
// canvas, or partly off it, still says its name). From attributes only: no layout.
const headAt = new WeakMap<Element, string>();
function stickLaneHeads(v: DiagramView): void {
  if (!v.view) return;
  const { W } = canvasSize();
  const { x: vx, y: vy, k } = v.view;
  for (const g of v.viewport.children) {
    if (!g.classList.contains("lane") || g.classList.contains("culled")) continue;
    const span = spanOf(g);
    const head = span.head;
    if (!head) continue;
    const left = Math.max(span.x, -vx / k);
    const right = Math.min(span.x + span.w, (W - vx) / k);
    if (right <= left) continue;
    const half = span.tw / 2 + 10;
    let cx = (left + right) / 2 - span.x;
    cx = span.w <= 2 * half ? span.w / 2 : Math.min(Math.max(cx, half), span.w - half);
    const laneH = Number(span.bg?.getAttribute("height") ?? 0);
    const dy = Math.max(0, Math.min(-vy / k - span.y, laneH - span.headH));
    const at = `${cx.toFixed(1)},${dy.toFixed(1)}`;
    if (headAt.get(head) === at) continue;
    headAt.set(head, at);
    if (dy > 0) head.setAttribute("transform", `translate(0,${dy.toFixed(1)})`);
    else head.removeAttribute("transform");
    for (const t of span.texts) t.setAttribute("x", cx.toFixed(1));
  }
}

/** Draw the lane of `el` (culled when it was off the canvas) so that it can be measured. */
function uncull(el: Element): void {
  el.closest("g.lane")?.classList.remove("culled");
}

/** Centre the view on a node (at a readable zoom) and flash it. */
function reveal(lane: string, node: string): void {
  const v = views.get(current);
  const g = canvas.querySelector<SVGGElement>(
    `g.node[data-lane="${CSS.escape(lane)}"][data-node="${CSS.escape(node)}"]`,
  );
  if (!v?.view || !g) return;
  setFollow(false); // the user asked to see this node: following would take the view away
  uncull(g);
  if (v.view.k < 0.8) {
    const r = canvas.getBoundingClientRect();
    const cx = r.width / 2;
    const cy = r.height / 2;
    v.view.x = cx - ((cx - v.view.x) * 0.9) / v.view.k;
    v.view.y = cy - ((cy - v.view.y) * 0.9) / v.view.k;
    v.view.k = 0.9;
    applyView(v);
  }
  uncull(g);
  const c = canvas.getBoundingClientRect();
  const b = g.getBoundingClientRect();
  v.view.x += c.left + c.width / 2 - (b.left + b.width / 2);
  v.view.y += c.top + c.height / 2 - (b.top + b.height / 2);
  applyView(v);
  g.animate([{ opacity: 0.2 }, { opacity: 1 }, { opacity: 0.2 }, { opacity: 1 }], { duration: 900 });
}

/** After an edit: a diagram that fits the canvas (at its zoom, or zoomed out to >= 0.6) is shown whole. */
function keepInView(v: DiagramView): void {
  if (!v.view) return;
  const { W, H } = canvasSize();
  const pad = 16;
  const kFit = Math.min((W - 2 * pad) / v.width, (H - 2 * pad) / v.height);
  if (kFit < v.view.k && kFit >= 0.6) {
    // grown past the canvas but still readable whole: zoom out to show all of it
    v.view.x = (W - v.width * kFit) / 2;
    v.view.y = (H - v.height * kFit) / 2;
    v.view.k = kFit;
  }
  const w = v.width * v.view.k;
  const h = v.height * v.view.k;
  if (w <= W - 2 * pad) v.view.x = Math.min(Math.max(v.view.x, pad), W - pad - w);
  if (h <= H - 2 * pad) v.view.y = Math.min(Math.max(v.view.y, pad), H - pad - h);
}

/** Pan (no zoom) so that `el` is inside the canvas. */
function showElement(v: DiagramView, el: Element): void {
  if (!v.view) return;
  uncull(el);
  const box = nodeBox(el);
  let c: { left: number; top: number; right: number; bottom: number };
  let b: { left: number; top: number; right: number; bottom: number };
  if (box) {
    // a node: where it is from its attributes (measuring it would lay the diagram out now)
    const { W, H } = canvasSize();
    const k = v.view.k;
    c = { left: 0, top: 0, right: W, bottom: H };
    b = {
      left: v.view.x + box.x * k,
      top: v.view.y + box.y * k,
      right: v.view.x + (box.x + box.w) * k,
      bottom: v.view.y + (box.y + box.h) * k,
    };
  } else {
    c = canvas.getBoundingClientRect();
    b = el.getBoundingClientRect();
  }
  const pad = 24;
  let dx = 0;
  let dy = 0;
  if (b.right > c.right - pad) dx = c.right - pad - b.right;
  if (b.left + dx < c.left + pad) dx = c.left + pad - b.left;
  if (b.bottom > c.bottom - pad) dy = c.bottom - pad - b.bottom;
  if (b.top + dy < c.top + pad) dy = c.top + pad - b.top;
  if (!dx && !dy) return;
  v.view.x += dx;
  v.view.y += dy;
  applyView(v);
}

// Zoom levels: below LOD_MID the stats, values and guards are not drawn, below LOD_FAR not even
// the nodes' names (applyView). A diagram opens whole when that is readable (READABLE_K or more);
// a bigger one opens at OPEN_K on its start node, from the top: Fit (f) shows all of it.
const LOD_MID = 0.45;
const LOD_FAR = 0.3;
const READABLE_K = 0.65; // 11 px texts at >= 7 px
const OPEN_K = 0.8;

/** Show the whole diagram; `readable`: when that is too small to read, a readable part from the top. */
function fit(v: DiagramView, readable = true): void {
  const { W, H } = canvasSize();
  const pad = 16;
  let k = Math.min((W - 2 * pad) / v.width, (H - 2 * pad) / v.height, 1.25);
  let y = (H - v.height * k) / 2;
  let x = (W - v.width * k) / 2;
  if (readable && k < READABLE_K) {
    // Too small to read when fitted whole: its width if that is readable, else OPEN_K, from the top,
    // around the start node (or the left edge).
    const kWidth = (W - 2 * pad) / v.width;
    k = kWidth >= READABLE_K ? Math.min(kWidth, 1) : OPEN_K;
    y = v.height * k > H - 2 * pad ? pad : (H - v.height * k) / 2;
    const w = v.width * k;
    if (w <= W - 2 * pad) x = (W - w) / 2;
    else {
      const fx = v.focus ? v.focus.x * k : 0;
      x = Math.min(pad, Math.max(W - pad - w, W / 2 - fx));
    }
  }
  k = Math.max(k, 0.02);
  v.view = { k, x, y };
  applyView(v);
}

$<HTMLButtonElement>("#fit").addEventListener("click", () => {
  const v = views.get(current);
  if (v) fit(v, false);
});

canvas.addEventListener(
  "wheel",
  (ev) => {
    const v = views.get(current);
    if (!v?.view) return;
    ev.preventDefault();
    const r = canvas.getBoundingClientRect();
    const px = ev.clientX - r.left;
    const py = ev.clientY - r.top;
    const f = Math.exp(-ev.deltaY * (ev.deltaMode === 1 ? 0.05 : 0.0015));
    const k = Math.min(8, Math.max(0.02, v.view.k * f));
    setFollow(false); // zoomed by hand: the view stays where the user put it
    v.view.x = px - ((px - v.view.x) * k) / v.view.k;
    v.view.y = py - ((py - v.view.y) * k) / v.view.k;
    v.view.k = k;
    applyView(v);
  },
  { passive: false },
);

let drag: { x: number; y: number; vx: number; vy: number; moved: boolean; id: number } | null = null;
canvas.addEventListener("pointerdown", (ev) => {
  if (editor?.pointerDown(ev)) {
    setFollow(false); // working on the diagram: it must not move away under the pointer
    return;
  }
  const v = views.get(current);
  if (!v?.view || ev.button !== 0) return;
  drag = { x: ev.clientX, y: ev.clientY, vx: v.view.x, vy: v.view.y, moved: false, id: ev.pointerId };
});
canvas.addEventListener("pointermove", (ev) => {
  const v = views.get(current);
  if (!drag || !v?.view || ev.pointerId !== drag.id) return;
  const dx = ev.clientX - drag.x;
  const dy = ev.clientY - drag.y;
  if (!drag.moved && Math.hypot(dx, dy) > 3) {
    drag.moved = true;
    setFollow(false); // panned by hand: the view stays where the user put it
    canvas.setPointerCapture(ev.pointerId);
    canvas.classList.add("dragging");
  }
  if (drag.moved) {
    v.view.x = drag.vx + dx;
    v.view.y = drag.vy + dy;
    applyView(v);
  }
});
const endDrag = (ev: PointerEvent): void => {
  if (!drag || ev.pointerId !== drag.id) return;
  const wasClick = !drag.moved;
  drag = null;
  canvas.classList.remove("dragging");
  if (wasClick) {
    // A click on a call behaviour action opens the called activity.
    const g = (ev.target as Element).closest?.("g.node.calls");
    const lane = g?.getAttribute("data-calls");
    if (lane && laneDiagram.has(lane)) select(laneDiagram.get(lane)!);
  }
};
canvas.addEventListener("pointerup", endDrag);
canvas.addEventListener("pointercancel", endDrag);

// ---------------------------------------------------------------- follow the running robot

// As a map app follows its user: the view pans (never zooms) to keep the node of the shown diagram
// that ran last in view when it leaves the canvas — checked at most every FOLLOW_EVERY_MS, a short
// pan eased over FOLLOW_PAN_MS, a long one at once. On by default (live and replay); a pan or
// zoom by hand, or taking hold of the diagram in the editor, turns it off; the toolbar's Follow
// button or the `l` key on again.
const FOLLOW_EVERY_MS = 250;
const FOLLOW_PAN_MS = 300;
const FOLLOW_MARGIN = 32; // px the node keeps from the canvas's edges
// A pan to a lane not drawn now (off the canvas: culled) draws it, a layout of its every node:
// at most one such pan a second (under thousands of events/s the last node jumps between lanes).
const FOLLOW_NEW_LANE_MS = 1000;
let followLaneAt = 0;
const followBtn = $<HTMLButtonElement>("#follow");
let followDue = false; // nodes ran (or the view changed) since the last check
let followAt = 0;
let followPan: { v: DiagramView; x0: number; y0: number; x1: number; y1: number; t0: number } | null = null;

function setFollow(on: boolean): void {
  hooks.follow = on;
  followBtn.setAttribute("aria-pressed", String(on));
  followBtn.title = on
    ? "Following the running robot: the view pans to the node that ran last (a pan or zoom by hand stops it; l)"
    : "Follow the running robot: pan to the node that ran last whenever it leaves the view (l)";
  followPan = null;
  if (on) {
    followDue = true;
    followAt = 0;
    schedule();
  }
}
followBtn.addEventListener("click", () => setFollow(!hooks.follow));

/** The node of diagram `id` that ran last (the latest of its lanes' current nodes), or null. */
function lastRan(id: string): string | null {
  let best: string | null = null;
  let bestIdx = -1;
  for (const lane of model?.diagrams.find((d) => d.id === id)?.lanes ?? []) {
    const now = state.trails.get(lane.name)?.[0];
    if (now === undefined) continue;
    const key = nodeKey(lane.name, now);
    const idx = state.nodes.get(key)?.lastIdx ?? -1;
    if (idx > bestIdx) {
      bestIdx = idx;
      best = key;
    }
  }
  return best;
}

/** One step of following, in the frame loop: the eased pan under way, else (at most every
 * FOLLOW_EVERY_MS) a look whether the node that ran last is still in view. */
function followStep(now: number): void {
  if (cullPending) {
    const v = cullPending;
    cullPending = views.get(current) === v && cullLanes(v, 1) ? v : null;
    stickLaneHeads(v);
    return;
  }
  if (followPan) {
    const p = followPan;
    const t = Math.min(1, (now - p.t0) / FOLLOW_PAN_MS);
    const e = t * t * (3 - 2 * t);
    if (p.v.view && views.get(current) === p.v) {
      p.v.view.x = p.x0 + (p.x1 - p.x0) * e;
      p.v.view.y = p.y0 + (p.y1 - p.y0) * e;
      applyView(p.v);
    }
    if (t >= 1 || views.get(current) !== p.v) followPan = null;
    return;
  }
  if (!hooks.follow || !followDue || now - followAt < FOLLOW_EVERY_MS) return;
  followDue = false;
  followAt = now;
  const v = views.get(current);
  const key = v?.view ? lastRan(current) : null;
  const g = key ? renderer.nodeEls.get(key)?.g : null;
  const box = g ? nodeBox(g) : null;
  if (!v?.view || !box) return;
  const { W, H } = canvasSize();
  const { x, y, k } = v.view;
  const left = x + box.x * k;
  const top = y + box.y * k;
  if (
    left >= FOLLOW_MARGIN &&
    top >= FOLLOW_MARGIN &&
    left + box.w * k <= W - FOLLOW_MARGIN &&
    top + box.h * k <= H - FOLLOW_MARGIN
  )
    return;
  if (g!.closest("g.lane")?.classList.contains("culled")) {
    if (now - followLaneAt < FOLLOW_NEW_LANE_MS) {
      followDue = true; // looked at again later
      return;
    }
    followLaneAt = now;
  }
  // centred on it (a node near an edge would leave again at once); eased when it is near, at once
  // when it is far (gliding over lanes in between would draw each of them on the way)
  const x1 = W / 2 - (box.x + box.w / 2) * k;
  const y1 = H / 2 - (box.y + box.h / 2) * k;
  hooks.followPans += 1;
  if (Math.hypot(x1 - x, y1 - y) > 0.75 * Math.max(W, H)) {
    v.view.x = x1;
    v.view.y = y1;
    applyView(v, 1);
  } else followPan = { v, x0: x, y0: y, x1, y1, t0: now };
}

// ---------------------------------------------------------------- calls and status panels

interface RowEl {
  tr: HTMLTableRowElement;
  row: CallRow;
}
let callRows = new Map<string, RowEl>();

const clockText = (t: number): string => {
  const d = new Date(t * 1000);
  return `${d.toLocaleTimeString([], { hour12: false })}.${String(d.getMilliseconds()).padStart(3, "0")}`;
};
function jsonText(v: unknown): string {
  try {
    const s = JSON.stringify(v);
    return s === undefined ? "" : s;
  } catch {
    return String(v);
  }
}

function fillRow(tr: HTMLTableRowElement, r: CallRow): void {
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

function newRow(r: CallRow): HTMLTableRowElement {
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

function flushCalls(full: boolean): void {
  const newest = state.newestCalls();
  if (full) {
    callRows = new Map();
    const frag = document.createDocumentFragment();
    for (const r of newest) {
      const tr = newRow(r);
      callRows.set(r.key, { tr, row: r });
      frag.append(tr);
    }
    callsBody.replaceChildren(frag);
    return;
  }
  const keep = new Set(newest.map((r) => r.key));
  for (const [key, re] of callRows) {
    if (!keep.has(key)) {
      re.tr.remove();
      callRows.delete(key);
    }
  }
  // new rows go on top; one listed below a row already shown (a time-out keeps its request's
  // time) rebuilds the table
  let top = true;
  for (const r of newest) {
    if (callRows.has(r.key)) top = false;
    else if (!top) {
      flushCalls(true);
      return;
    }
  }
  const frag = document.createDocumentFragment();
  for (const r of newest) {
    const re = callRows.get(r.key);
    if (!re) {
      const tr = newRow(r);
      callRows.set(r.key, { tr, row: r });
      frag.append(tr);
    } else if (re.row !== r) {
      re.row = r;
      fillRow(re.tr, r);
    }
  }
  callsBody.prepend(frag);
}

function flushStatus(): void {
  const o = state.orch;
  orchEl.dataset.state = o.state;
  let text = `orchestrator: ${o.state}`;
  if (o.detail) text += ` — ${o.detail}`;
  if (state.exitPayload !== undefined) text += ` · exit ${jsonText(state.exitPayload)}`;
  orchEl.textContent = text;
  orchEl.title = text; // the pill may be cut short: the whole text on hover
  updateGaps();
}

let frameGaps = 0;
let lostFrames = 0;
let dropped = 0;
function updateGaps(): void {
  const lostTrace = state.traceLost;
  gapsEl.dataset.gaps = String(frameGaps);
  gapsEl.dataset.lostFrames = String(lostFrames);
  gapsEl.dataset.dropped = String(dropped);
  gapsEl.dataset.lostTrace = String(lostTrace);
  const parts: string[] = [];
  if (frameGaps)
    parts.push(
      `${frameGaps} gap${frameGaps === 1 ? "" : "s"} in the stream (${lostFrames} frame${lostFrames === 1 ? "" : "s"} lost)`,
    );
  if (dropped) parts.push(`${dropped} events dropped by the server`);
  if (lostTrace) parts.push(`${lostTrace} trace events lost`);
  gapsEl.hidden = parts.length === 0;
  gapsEl.textContent = parts.length ? `⚠ ${parts.join(" · ")}` : "";
}

// ---------------------------------------------------------------- frame loop

const queue: MonitorEvent[] = [];
let qpos = 0;
let rafId = 0;
let lastTs = 0;
let lastArrival = 0;
const BUDGET_MS = 8; // applying queued events, per frame
const RENDER_BUDGET_MS = 8; // node updates, per frame

function schedule(): void {
  if (!rafId) rafId = requestAnimationFrame(tick);
}

/** Apply the state's changes to the page. */
const pulsedAt = new Map<string, number>();
/** Pulse the list entry of each diagram whose lanes ran (at most every 300 ms per diagram). */
function pulseDiagrams(): void {
  if (!state.dirtyLanes.size) return;
  const now = performance.now();
  const seen = new Set<string>();
  for (const lane of state.dirtyLanes) {
    const id = laneDiagram.get(lane);
    if (!id || seen.has(id)) continue;
    seen.add(id);
    if (now - (pulsedAt.get(id) ?? -1e9) < 300) continue;
    pulsedAt.set(id, now);
    const dot = listEl.querySelector<HTMLElement>(`li[data-diagram="${CSS.escape(id)}"] .pulse`);
    dot?.animate([{ opacity: 1 }, { opacity: 0 }], { duration: 1500, fill: "forwards" });
  }
}

function render(budgetMs = 0): void {
  pulseDiagrams();
  const full = state.allDirty;
  renderer.flush(state, budgetMs);
  if (state.dirtyCalls) flushCalls(full);
  if (state.dirtyOrch || full) flushStatus();
  state.clearDirty();
}

/** The last edit is shown once the diagram draws its version and every node change (its
 * diagnostics among them) is drawn: the end of this frame (`window.__studio.edit.timings`). */
function noteEditShown(): void {
  const timings = hooks.edit?.timings ?? [];
  const last = timings[timings.length - 1];
  if (last && last.shown === undefined && hooks.edit!.drawn >= last.version && !state.dirtyNodes.size) {
    last.shown = performance.now();
  }
}

let skippedDraw = false;
// node end times (unix s) of the live trace events applied but not drawn yet: each one's latency
// (node end -> drawn) is recorded when the frame that shows it is drawn
const unshownEnds: number[] = [];

function tick(ts: number): void {
  rafId = 0;
  const flowing = performance.now() - lastArrival < 1000 || !!replay?.playing;
  const frameMs = lastTs ? ts - lastTs : 0;
  if (flowing && lastTs) pushCapped(hooks.frames, frameMs);
  lastTs = ts;

  if (mode === "live" && qpos < queue.length) {
    const t0 = performance.now();
    while (qpos < queue.length) {
      const e = queue[qpos++];
      state.apply(e);
      if (e.type === "trace") {
        hooks.applied += 1;
        unshownEnds.push(e.time);
        followDue = true;
      }
      if ((qpos & 255) === 0 && performance.now() - t0 > BUDGET_MS) break;
    }
    if (qpos >= queue.length) {
      queue.length = 0;
      qpos = 0;
    }
  }
  if (mode === "replay" && replay) replayTick(ts);

  // When frames run late (a busy machine), draw every other frame only: events are still
  // applied, the drawing catches up on the next frame.
  if (frameMs > 24 && !skippedDraw && !state.allDirty) {
    skippedDraw = true;
  } else {
    skippedDraw = false;
    render(RENDER_BUDGET_MS);
    noteEditShown();
    followStep(performance.now());
    sim.flush();
    if (unshownEnds.length) {
      const now = Date.now();
      for (const end of unshownEnds) pushCapped(hooks.latencies, now - end * 1000);
      unshownEnds.length = 0;
    }
  }

  const following = followPan !== null || cullPending !== null || (hooks.follow && followDue);
  if (qpos < queue.length || flowing || skippedDraw || state.dirtyNodes.size || replay?.playing || following)
    schedule();
  else lastTs = 0;
}

// ---------------------------------------------------------------- broker status

// The studio's own connection to the broker (not the page's socket to the studio): without it
// the page can show nothing of the robot, so it says why and when the next attempt is.
// While a Run of the editor goes on, the toolbar shows the connection to that run's own broker
// (the simulator's), reported like the robot's; after the run, the robot's broker again.
interface BrokerSeen {
  e: MonitorEvent;
  retryAt: number;
}
let brokerLast: BrokerSeen | null = null;
let runBroker: BrokerSeen | null = null;
let runActive = false;
let brokerTimer = 0;

function showBroker(e: MonitorEvent): void {
  const seen = { e, retryAt: e.retry_in_s !== undefined ? performance.now() + e.retry_in_s * 1000 : 0 };
  if (e.source === "run") runBroker = seen;
  else brokerLast = seen;
  drawBroker();
}

/** A Run started or ended: the toolbar shows whose broker connection is relevant now. */
function setRunActive(active: boolean): void {
  runActive = active;
  if (active) runBroker = null; // this run's broker, not the last run's
  drawBroker();
}

function drawBroker(): void {
  const run = runActive && runBroker !== null;
  const seen = run ? runBroker : brokerLast;
  const connected = !!seen?.e.connected;
  if (!connected && seen && !brokerTimer) brokerTimer = window.setInterval(drawBroker, 1000);
  if ((connected || !seen) && brokerTimer) {
    window.clearInterval(brokerTimer);
    brokerTimer = 0;
  }
  brokerEl.dataset.source = run ? "run" : "robot";
  if (!seen) {
    brokerEl.hidden = true;
    return;
  }
  const e = seen.e;
  const brokerRetryAt = seen.retryAt;
  brokerEl.hidden = false;
  brokerEl.title = e.url ?? "";
  const who = run ? "sim broker" : "broker";
  if (e.connected) {
    brokerEl.title = run
      ? `connected to the simulator's own broker of this run (${e.url ?? ""})`
      : `connected to ${e.url ?? "the broker"}`;
    brokerEl.dataset.state = "connected";
    brokerEl.textContent = `${who} connected`;
    return;
  }
  brokerEl.dataset.state = e.problem ? "failed" : "connecting";
  let text = `${who} ${e.url ?? ""}: ${e.problem ?? "connecting…"}`;
  if (e.problem) {
    const left = Math.max(0, Math.ceil((brokerRetryAt - performance.now()) / 1000));
    text += left > 0 ? `, retrying in ${left} s` : ", retrying…";
    if ((e.attempts ?? 0) > 1) text += ` (attempt ${e.attempts})`;
  }
  brokerEl.textContent = text;
  brokerEl.title = text; // the toolbar may cut it short
}

// ---------------------------------------------------------------- replay

// A snapshot of the state every SNAP_EVERY events, further apart when the duration histograms
// it would keep (copied since the last one) exceed COUNTERS_PER_EVENT per event since then: the
// snapshots' histograms take at most ~64 bytes per event of the trace (less than the event
// itself), and a seek applies at most the events between two snapshots (~20 ms for the 22 000
// of a trace spread evenly over 2 000 nodes).
const SNAP_EVERY = 1000;
const COUNTERS_PER_EVENT = 8;
interface Replay {
  events: MonitorEvent[];
  times: Float64Array;
  t0: number;
  duration: number;
  snaps: Snapshot[];
  snapPos: number[]; // events applied before each snapshot (ascending)
  pos: number; // events applied
  time: number; // seconds since the first event
  playing: boolean;
  prevTs: number;
  pendingTrace: MonitorEvent | null;
}
let replay: Replay | null = null;

function setupReplay(events: MonitorEvent[], notes: string[]): void {
  replayNotesEl.hidden = notes.length === 0;
  replayNotesEl.textContent = notes.map((n) => `⚠ ${n}`).join("  ");
  replayNotesEl.title = notes.join("\n");
  const sorted = events
    .map((e, i) => ({ e, i }))
    .sort((a, b) => a.e.time - b.e.time || a.i - b.i)
    .map((x) => x.e);
  const times = new Float64Array(sorted.length);
  sorted.forEach((e, i) => {
    times[i] = e.time;
  });
  const t0 = sorted.length ? sorted[0].time : 0;
  const snaps: Snapshot[] = [];
  const snapPos: number[] = [];
  let since = 0;
  for (let i = 0; i < sorted.length; i++) {
    if (i === 0 || (since >= SNAP_EVERY && COUNTERS_PER_EVENT * since >= state.ownedCounters)) {
      snaps.push(state.snapshot());
      snapPos.push(i);
      since = 0;
    }
    state.apply(sorted[i]);
    since += 1;
  }
  const duration = sorted.length ? sorted[sorted.length - 1].time - t0 : 0;
  replay = {
    events: sorted,
    times,
    t0,
    duration,
    snaps,
    snapPos,
    pos: 0,
    time: 0,
    playing: false,
    prevTs: 0,
    pendingTrace: null,
  };
  state.restore(snaps[0] ?? state.snapshot());
  timeInput.min = "0";
  timeInput.max = duration.toFixed(3);
  timeInput.step = "0.001";
  replayEl.hidden = false;
  seek(0);
  updatePlay();
}

function upperBound(a: ArrayLike<number>, v: number): number {
  let lo = 0;
  let hi = a.length;
  while (lo < hi) {
    const mid = (lo + hi) >> 1;
    if (a[mid] <= v) lo = mid + 1;
    else hi = mid;
  }
  return lo;
}

function seek(t: number): void {
  if (!replay) return;
  const r = replay;
  r.time = Math.min(Math.max(t, 0), r.duration);
  const target = upperBound(r.times, r.t0 + r.time + 1e-9);
  const s = upperBound(r.snapPos, target) - 1; // the last snapshot at or before the target
  if (s >= 0 && (target < r.pos || r.snapPos[s] > r.pos)) {
    state.restore(r.snaps[s]);
    r.pos = r.snapPos[s];
  }
  while (r.pos < target) {
    const e = r.events[r.pos++];
    state.apply(e);
    if (e.type === "trace") {
      hooks.applied += 1;
      r.pendingTrace = e;
      followDue = true;
    }
  }
  if (document.activeElement !== timeInput || r.playing) timeInput.value = r.time.toFixed(3);
  clockEl.textContent = `${r.time.toFixed(3)} s / ${r.duration.toFixed(3)} s`;
  schedule();
}

function replayTick(ts: number): MonitorEvent | null {
  const r = replay!;
  if (r.playing) {
    if (r.prevTs) {
      const speed = Number(speedSel.value) || 1;
      const t = r.time + ((ts - r.prevTs) / 1000) * speed;
      if (t >= r.duration) {
        r.playing = false;
        updatePlay();
      }
      seek(t);
    }
    r.prevTs = ts;
  }
  const e = r.pendingTrace;
  r.pendingTrace = null;
  return e;
}

function updatePlay(): void {
  const playing = !!replay?.playing;
  playBtn.textContent = playing ? "❚❚ Pause" : "▶ Play";
  playBtn.setAttribute("aria-pressed", String(playing));
}

playBtn.addEventListener("click", () => {
  if (!replay) return;
  if (!replay.playing && replay.time >= replay.duration) seek(0);
  replay.playing = !replay.playing;
  replay.prevTs = 0;
  updatePlay();
  schedule();
});
timeInput.addEventListener("input", () => {
  if (!replay) return;
  seek(Number(timeInput.value));
  render(); // a scrub shows its moment at once, not a frame later
});

// ---------------------------------------------------------------- editing

/** Forget the counts of the previous run (a new run starts). */
function resetLive(): void {
  queue.length = 0;
  qpos = 0;
  state = new StudioState(index);
  callRows = new Map();
  callsBody.replaceChildren();
  state.markAllDirty();
  schedule();
}

const editorHost = {
  canvas,
  model: (): ModelView | null => model,
  current: (): string => current,
  scale: (): number => views.get(current)?.view?.k ?? 1,
  select,
  setModel: (m: ModelView | null, d: Diagnostic[]): void => {
    if (!m && model && !editor?.info.empty) {
      // Broken by an edit: keep the last good diagrams, list the problems.
      setDiagnostics(d);
      bannerEl.textContent =
        "The model does not compile now (see Diagnostics): the diagram shows its last version that did.";
      bannerEl.hidden = false;
    } else {
      bannerEl.hidden = true;
      setModel(m, d, true);
    }
    schedule();
  },
  relayout: (): void => setModel(model, diagnostics),
  diagnostics: (): Diagnostic[] => diagnostics,
  resetLive,
};

// ---------------------------------------------------------------- connection

let ws: WebSocket | null = null;
/** The close code of a page the studio dropped for falling behind (umlbot/studio/hub.py). */
const CLOSE_TOO_SLOW = 4000;
let expectSeq = 0;
let retry = 500;

function resetSession(hello: HelloMsg): void {
  hooks.hellos += 1;
  bannerEl.hidden = true;
  mode = hello.mode === "replay" ? "replay" : "live";
  queue.length = 0;
  qpos = 0;
  replay = null;
  replayEl.hidden = true;
  expectSeq = 0;
  frameGaps = 0;
  lostFrames = 0;
  dropped = 0;
  // The editor draws the model as written (it exists while the model has errors too).
  const shown = hello.edit ? (hello.edit.model ?? null) : hello.model;
  const shownDiagnostics = hello.edit ? (hello.edit.diagnostics ?? hello.diagnostics ?? []) : (hello.diagnostics ?? []);
  index = new ModelIndex(shown);
  state = new StudioState(index);
  callRows = new Map();
  callsBody.replaceChildren();
  robotName = hello.robot;
  // an empty folder has no name yet (the robot is followed under the name it is given)
  const fresh = !!hello.edit?.empty;
  const name = shown?.name ?? (fresh ? "new model" : "(no model)");
  titleEl.textContent = fresh ? name : `${name} · robot ${hello.robot}`;
  $<HTMLElement>("#source").textContent = hello.source;
  $<HTMLElement>("#source").title = hello.source;
  titleEl.title = hello.source;
  modeEl.textContent = mode === "replay" ? `replay${hello.replay ? ` · ${hello.replay.file}` : ""}` : "live";
  modeEl.dataset.mode = mode;
  document.title = `umlbot studio — ${name} (${mode})`;
  // (a *Run* going on or ended draws its track: the world frame after the snapshot puts the car)
  sim.setTrack(hello.track ?? hello.edit?.run?.track ?? null);
  if (hello.edit) {
    if (editor) editor.setInfo(hello.edit);
    else {
      hooks.edit = {
        version: hello.edit.version,
        busy: false,
        dirty: hello.edit.dirty,
        requests: 0,
        errors: [],
        drawn: -1,
        timings: [],
      };
      editor = new Editor(editorHost, hello.edit, hooks.edit);
    }
  }
  setModel(shown, shownDiagnostics);
  if (hello.edit) editor?.afterHello(hello.edit);
  brokerEl.hidden = true; // until the broker source says how its connection is
  brokerLast = null;
  runBroker = null;
  runActive = !!hello.edit?.run?.running;
  if (mode === "replay") setupReplay(hello.replay?.events ?? [], hello.replay?.notes ?? []);
  state.markAllDirty();
  schedule();
}

function onMessage(msg: ServerMsg): void {
  switch (msg.type) {
    case "hello":
      resetSession(msg);
      break;
    case "events": {
      if (expectSeq && msg.seq !== expectSeq) {
        frameGaps += 1;
        if (msg.seq > expectSeq) lostFrames += msg.seq - expectSeq;
      }
      expectSeq = msg.seq + 1;
      dropped += msg.dropped ?? 0;
      if (mode === "live") {
        for (const e of msg.events) {
          if (e.type === "broker") showBroker(e);
          else queue.push(e);
        }
        lastArrival = performance.now();
      }
      state.dirtyOrch = true;
      schedule();
      break;
    }
    case "world":
      sim.push(msg);
      schedule();
      break;
    case "files":
      editor?.onFiles(msg);
      schedule();
      break;
    case "conflict":
      editor?.onConflict(msg);
      break;
    case "run":
      setRunActive(msg.state === "running");
      if (msg.state === "running") {
        // a new run: the sim panel shows its track, the counts start from zero
        sim.setTrack(msg.track ?? null);
        resetLive();
      }
      editor?.onRun(msg);
      break;
    case "robot":
      // the robot id follows the model's name: what the page showed was the previous robot's
      robotName = msg.robot;
      titleEl.textContent = `${model?.name ?? "(no model)"} · robot ${robotName}`;
      resetLive();
      break;
    case "model":
      if (!msg.model && model) {
        // Broken by an edit: keep the last good diagrams, list the problems.
        setDiagnostics(msg.diagnostics ?? []);
        bannerEl.textContent = "The model no longer compiles (see Diagnostics): showing the last version that did.";
        bannerEl.hidden = false;
      } else {
        bannerEl.hidden = true;
        setModel(msg.model, msg.diagnostics ?? []);
      }
      schedule();
      break;
    default:
      break;
  }
}

// The editor asks for a fresh hello (the server's working copy) after a stale edit.
window.addEventListener("studio-resync", () => ws?.close());

function connect(): void {
  const url = `${location.protocol === "https:" ? "wss" : "ws"}://${location.host}/ws`;
  const sock = new WebSocket(url);
  ws = sock;
  sock.onopen = () => {
    retry = 500;
    connEl.dataset.state = "open";
    connEl.textContent = "● connected";
  };
  sock.onmessage = (ev) => {
    let msg: ServerMsg;
    try {
      msg = JSON.parse(ev.data as string) as ServerMsg;
    } catch (err) {
      console.error("studio: bad frame", err);
      return;
    }
    onMessage(msg);
  };
  sock.onclose = (ev) => {
    if (ws !== sock) return;
    connEl.dataset.state = "closed";
    // the studio drops a page that fell behind (CLOSE_TOO_SLOW) and says why: the page starts
    // again from a fresh hello and snapshot
    const why = ev.code === CLOSE_TOO_SLOW && ev.reason ? ev.reason : "disconnected";
    connEl.dataset.closeCode = String(ev.code);
    connEl.textContent = `○ ${why} — reconnecting…`;
    connEl.title = ev.reason || "";
    setTimeout(connect, retry);
    retry = Math.min(retry * 2, 5000);
  };
}

window.addEventListener("keydown", (ev) => {
  if (editor?.key(ev)) return;
  const t = ev.target as HTMLElement;
  if (ev.ctrlKey || ev.metaKey || ev.altKey || /^(INPUT|SELECT|TEXTAREA|BUTTON)$/.test(t.tagName)) return;
  if (ev.key === " " && replay) {
    ev.preventDefault();
    playBtn.click();
  } else if (ev.key === "f") {
    const v = views.get(current);
    if (v) fit(v, false);
  } else if (ev.key === "l") {
    setFollow(!hooks.follow);
  }
});

connEl.dataset.state = "closed";
connEl.textContent = "○ connecting…";
setFollow(true); // live and replay both start following
updateGaps();
warmUp();
connect();
