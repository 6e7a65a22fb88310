// Which action a key press is: the editor's keys first, then the viewer's. Pure
// (test/keyboard.test.ts).

/** What matters of a key press. */
export interface KeyPress {
  key: string;
  ctrl: boolean;
  meta: boolean;
  alt: boolean;
  shift: boolean;
  /** the tag name of the element the key goes to */
  tag: string;
  /** it goes to an <input> with nothing typed in it (its text as the page wrote it) */
  untouchedInput: boolean;
}

export type EditAction = "save" | "undo" | "redo" | "cancel" | "delete";
export type ViewAction =
  | "play"
  | "fit"
  | "follow"
  | "zoom-in"
  | "zoom-out"
  | "pan-left"
  | "pan-right"
  | "pan-up"
  | "pan-down";

const VIEW_KEYS = new Map<string, ViewAction>([
  [" ", "play"],
  ["f", "fit"],
  ["l", "follow"],
  ["+", "zoom-in"],
  ["=", "zoom-in"],
  ["-", "zoom-out"],
  ["ArrowLeft", "pan-left"],
  ["ArrowRight", "pan-right"],
  ["ArrowUp", "pan-up"],
  ["ArrowDown", "pan-down"],
]);

/** The editor's action for a key press (null: not the editor's). Ctrl-S saves from anywhere;
 * while something is typed in a field, its keys are the field's (its own text undo); with nothing
 * typed (e.g. the name field a new node focuses), Ctrl-Z and Ctrl-Y are the model's undo/redo.
 * Esc ends connecting; Delete or Backspace deletes the selection (`selected`). */
export function editAction(p: KeyPress, selected: boolean): EditAction | null {
  const typing = /^(INPUT|SELECT|TEXTAREA)$/.test(p.tag);
  const mod = p.ctrl || p.meta;
  const k = p.key.toLowerCase();
  if (mod && k === "s") return "save";
  if (typing && !(mod && (k === "z" || k === "y") && p.untouchedInput)) return null;
  if (mod && k === "z") return p.shift ? "redo" : "undo";
  if (mod && k === "y") return "redo";
  if (p.key === "Escape") return "cancel";
  if ((p.key === "Delete" || p.key === "Backspace") && selected) return "delete";
  return null;
}

/** The viewer's action for a key press (null: none; keys with a modifier, or typed into a field or
 * a button, are theirs): space plays, f fits, l follows, + and - zoom, the arrows pan. */
export function viewAction(p: KeyPress): ViewAction | null {
  if (p.ctrl || p.meta || p.alt || /^(INPUT|SELECT|TEXTAREA|BUTTON)$/.test(p.tag)) return null;
  return VIEW_KEYS.get(p.key) ?? null;
}
