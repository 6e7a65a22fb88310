// Where a dragged node or component is put. Pure (test/connect.test.ts).

/** An element dragged by (dx, dy) screen pixels at zoom k from its place (x, y) in diagram units:
 * its new place, whole units, never left of or above the diagram's origin. */
export function droppedAt(x: number, y: number, dx: number, dy: number, k: number): [number, number] {
  return [Math.round(Math.max(0, x + dx / k)), Math.round(Math.max(0, y + dy / k))];
}
