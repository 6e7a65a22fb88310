// How values are written on the page. Pure.

/** A value as JSON (what does not serialise: as String does). */
export function jsonText(v: unknown): string {
  try {
    const s = JSON.stringify(v);
    return s === undefined ? "" : s;
  } catch {
    return String(v);
  }
}

/** A unix time (s) as the wall clock's time of day with milliseconds. */
export function clockText(t: number): string {
  const d = new Date(t * 1000);
  return `${d.toLocaleTimeString([], { hour12: false })}.${String(d.getMilliseconds()).padStart(3, "0")}`;
}
