// The call/guard editor's pure parts: when a completion is offered, and the text once one is
// accepted (test/properties.test.ts).

import type { Completion } from "../../model/types";

/** Nothing is offered right after a closed call, a number or a string. */
export function offersAfter(textBeforeCursor: string): boolean {
  const prev = textBeforeCursor.trimEnd().slice(-1);
  return !/[)\]0-9'"]/.test(prev);
}

/** The text and cursor once `item` is accepted at `cursor` of `value`: it replaces the server's
 * `replace` range, else the word being typed (after the last dot) with the rest of that word. */
export function accept(
  value: string,
  cursor: number,
  item: Completion,
  replace?: [number, number],
): { value: string; at: number } {
  const text = item.insert ?? item.label;
  let from = replace?.[0];
  let to = replace?.[1];
  if (from === undefined || to === undefined) {
    const word = /[A-Za-z_][A-Za-z0-9_]*$/.exec(value.slice(0, cursor));
    from = word ? cursor - word[0].length : cursor;
    to = cursor;
    const after = /^[A-Za-z0-9_]*/.exec(value.slice(cursor));
    if (after) to += after[0].length;
  }
  return { value: value.slice(0, from) + text + value.slice(to), at: from + text.length };
}
