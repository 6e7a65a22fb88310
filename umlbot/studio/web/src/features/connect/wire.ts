// A flow being drawn with the pointer: a line from a node's output port to the pointer, over the
// canvas, until the button is released; then the node under the pointer (or none).

export interface Dropped {
  lane: string;
  id: string;
}

export function dragFlow(
  canvasEl: HTMLElement,
  ev: PointerEvent,
  port: Element,
  done: (to: Dropped | null) => void,
): void {
  const box = canvasEl.getBoundingClientRect();
  const p = port.getBoundingClientRect();
  const x0 = p.left + p.width / 2 - box.left;
  const y0 = p.top + p.height / 2 - box.top;
  const ns = "http://www.w3.org/2000/svg";
  const svg = document.createElementNS(ns, "svg");
  svg.setAttribute("class", "wire");
  const line = document.createElementNS(ns, "line");
  for (const [k, v] of Object.entries({ x1: x0, y1: y0, x2: x0, y2: y0 })) line.setAttribute(k, String(v));
  svg.append(line);
  canvasEl.append(svg);
  canvasEl.classList.add("wiring");
  const id = ev.pointerId;
  canvasEl.setPointerCapture(id);
  let over: Element | null = null;
  const nodeAt = (e: PointerEvent): Element | null => {
    const hit = document.elementsFromPoint(e.clientX, e.clientY).find((el) => el.closest("g.node"));
    return hit?.closest("g.node") ?? null;
  };
  const move = (e: PointerEvent): void => {
    if (e.pointerId !== id) return;
    line.setAttribute("x2", String(e.clientX - box.left));
    line.setAttribute("y2", String(e.clientY - box.top));
    const now = nodeAt(e);
    if (now !== over) {
      over?.classList.remove("drop-target");
      now?.classList.add("drop-target");
      over = now;
    }
  };
  const end = (e: PointerEvent): void => {
    if (e.pointerId !== id) return;
    canvasEl.removeEventListener("pointermove", move);
    canvasEl.removeEventListener("pointerup", end);
    canvasEl.removeEventListener("pointercancel", end);
    canvasEl.classList.remove("wiring");
    svg.remove();
    over?.classList.remove("drop-target");
    const to = e.type === "pointerup" ? nodeAt(e) : null;
    done(to ? { lane: to.getAttribute("data-lane") ?? "", id: to.getAttribute("data-node") ?? "" } : null);
  };
  canvasEl.addEventListener("pointermove", move);
  canvasEl.addEventListener("pointerup", end);
  canvasEl.addEventListener("pointercancel", end);
}
