// Small DOM helpers every feature uses.

/** The page's element for `sel` (index.html has it: a missing one is a bug of the page). */
export const $ = <T extends HTMLElement>(sel: string): T => document.querySelector(sel) as T;

/** A new element with attributes, appended to `parent`, holding `text`. */
export function el<K extends keyof HTMLElementTagNameMap>(
  tag: K,
  attrs: Record<string, string> = {},
  parent?: Element | null,
  text?: string,
): HTMLElementTagNameMap[K] {
  const e = document.createElement(tag);
  for (const [k, v] of Object.entries(attrs)) e.setAttribute(k, v);
  if (text !== undefined) e.textContent = text;
  if (parent) parent.append(e);
  return e;
}
