/** Paths of one file as the model view and a diagnostic write them (one may be relative to the model). */
export function sameFile(a: string, b: string): boolean {
  return a === b || a.endsWith(`/${b}`) || b.endsWith(`/${a}`);
}
