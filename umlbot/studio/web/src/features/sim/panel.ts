// The sim panel: track walls, goal, start, the car (pose) and its sonar pings, in world metres.

import { svgEl } from "../../draw/render";
import type { TrackView, WorldMsg } from "../../model/types";

const PING_SECONDS = 1.0; // pings of the last second (sim time) stay drawn
const PINGS_MAX = 400;

export class SimPanel {
  root: HTMLElement;
  svg: SVGSVGElement | null = null;
  /** the row that holds the track's picture, and beside it the camera's (depth.ts) */
  body: HTMLElement | null = null;
  private car: SVGGElement | null = null;
  private pingsG: SVGGElement | null = null;
  private info: HTMLElement | null = null;
  private pending: WorldMsg[] = [];

  constructor(root: HTMLElement) {
    this.root = root;
  }

  setTrack(track: TrackView | null): void {
    this.root.replaceChildren();
    this.svg = null;
    this.body = null;
    this.car = null;
    this.pingsG = null;
    this.root.hidden = !track;
    if (!track) return;
    const head = document.createElement("div");
    head.className = "panel-title";
    head.textContent = `Sim · ${track.name}`;
    this.info = document.createElement("span");
    this.info.className = "sim-info";
    head.append(" ", this.info);
    this.root.append(head);
    const xs: number[] = [track.goal.x_min, track.goal.x_max, track.start.x];
    const ys: number[] = [track.goal.y_min, track.goal.y_max, track.start.y];
    for (const w of track.walls)
      for (const [x, y] of w) {
        xs.push(x);
        ys.push(y);
      }
    const pad = 0.2;
    const x0 = Math.min(...xs) - pad;
    const x1 = Math.max(...xs) + pad;
    const y0 = Math.min(...ys) - pad;
    const y1 = Math.max(...ys) + pad;
    const svg = svgEl("svg", { viewBox: `${x0} ${-y1} ${x1 - x0} ${y1 - y0}`, preserveAspectRatio: "xMidYMid meet" });
    // y up: flip the world.
    const world = svgEl("g", { transform: "scale(1,-1)" }, svg);
    const g = track.goal;
    svgEl(
      "rect",
      { class: "goal", x: g.x_min, y: g.y_min, width: g.x_max - g.x_min, height: g.y_max - g.y_min },
      world,
    );
    for (const w of track.walls) {
      svgEl("polyline", { class: "wall", points: w.map(([x, y]) => `${x},${y}`).join(" ") }, world);
    }
    const s = track.start;
    svgEl("circle", { class: "start", cx: s.x, cy: s.y, r: 0.04 }, world);
    this.pingsG = svgEl("g", { class: "pings" }, world);
    const L = track.car.length_m;
    const W = track.car.width_m;
    this.car = svgEl("g", { class: "car", transform: `translate(${s.x},${s.y}) rotate(${s.heading_deg})` }, world);
    svgEl("rect", { class: "body", x: -L / 2, y: -W / 2, width: L, height: W, rx: Math.min(L, W) * 0.15 }, this.car);
    svgEl(
      "path",
      {
        class: "nose",
        d: `M${L / 2},0 L${L / 2 - Math.min(L, W) * 0.5},${W * 0.3} L${L / 2 - Math.min(L, W) * 0.5},${-W * 0.3} z`,
      },
      this.car,
    );
    this.svg = svg;
    this.body = document.createElement("div");
    this.body.className = "sim-body";
    this.body.append(svg);
    this.root.append(this.body);
  }

  push(msg: WorldMsg): void {
    this.pending.push(msg);
  }

  /** Draw what arrived since the last frame. */
  flush(): void {
    if (!this.pending.length || !this.car || !this.pingsG) {
      this.pending.length = 0;
      return;
    }
    const last = this.pending[this.pending.length - 1];
    const c = last.car;
    this.car.setAttribute("transform", `translate(${c.x},${c.y}) rotate(${c.heading_deg})`);
    for (const m of this.pending) {
      for (const p of m.pings) {
        svgEl(
          "line",
          {
            class: p.cm === null ? "ping miss" : "ping",
            x1: p.x0,
            y1: p.y0,
            x2: p.x1,
            y2: p.y1,
            "data-cm": p.cm === null ? "" : p.cm,
            "data-t": p.t,
          },
          this.pingsG,
        );
      }
    }
    // Keep the last second of pings, older ones fainter.
    const now = last.t;
    const lines = Array.from(this.pingsG.children) as SVGElement[];
    let drop = Math.max(0, lines.length - PINGS_MAX);
    const stale = (el: SVGElement): boolean => Math.abs(now - Number(el.getAttribute("data-t"))) > PING_SECONDS;
    while (drop < lines.length && stale(lines[drop])) drop++; // (a new run restarts the clock)
    for (let i = 0; i < drop; i++) lines[i].remove();
    for (let i = drop; i < lines.length; i++) {
      const age = Math.max(0, now - Number(lines[i].getAttribute("data-t")));
      lines[i].style.opacity = (1 - (0.75 * age) / PING_SECONDS).toFixed(2);
    }
    if (this.info) {
      const hits = last.collisions
        ? `hit a wall ${last.collisions === 1 ? "once" : `${last.collisions} times`}`
        : "no collisions";
      this.info.textContent = `${last.t.toFixed(1)} s driven (simulated time) · sonar turned to ${last.servo_deg.toFixed(0)}° · ${hits}${last.goal ? " · goal reached" : ""}`;
      this.info.title = "The simulated car's own clock: the same at any run speed";
    }
    this.pending.length = 0;
  }
}
