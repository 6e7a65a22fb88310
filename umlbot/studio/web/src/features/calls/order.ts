// Where the Calls panel's new rows go. Pure (test/calls.test.ts).

/** New rows go on top; a row that is not shown yet listed below one that is (a time-out keeps its
 * request's time) needs the table built again. Pure. */
export function needsRebuild(newestKeys: string[], shown: { has(key: string): boolean }): boolean {
  let top = true;
  for (const key of newestKeys) {
    if (shown.has(key)) top = false;
    else if (!top) return true;
  }
  return false;
}
