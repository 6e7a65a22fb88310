// A new node's id. Pure (test/palette.test.ts).

/** The first of `<kind>1`, `<kind>2`, … that `ids` does not hold. */
export function newNodeId(kind: string, ids: Set<string>): string {
  let n = 1;
  while (ids.has(`${kind}${n}`)) n += 1;
  return `${kind}${n}`;
}
