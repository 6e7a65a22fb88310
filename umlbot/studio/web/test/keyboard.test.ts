import assert from "node:assert/strict";
import { test } from "node:test";
import { editAction, type KeyPress, viewAction } from "../src/features/keyboard/keymap";

const key = (k: string, more: Partial<KeyPress> = {}): KeyPress => ({
  key: k,
  ctrl: false,
  meta: false,
  alt: false,
  shift: false,
  tag: "BODY",
  untouchedInput: false,
  ...more,
});

test("the editor's keys: save from anywhere, undo/redo, Esc, Delete with a selection", () => {
  assert.equal(editAction(key("s", { ctrl: true }), false), "save");
  assert.equal(editAction(key("S", { meta: true, tag: "INPUT" }), false), "save"); // even while typing
  assert.equal(editAction(key("z", { ctrl: true }), false), "undo");
  assert.equal(editAction(key("Z", { ctrl: true, shift: true }), false), "redo");
  assert.equal(editAction(key("y", { ctrl: true }), false), "redo");
  assert.equal(editAction(key("Escape"), false), "cancel");
  assert.equal(editAction(key("Delete"), true), "delete");
  assert.equal(editAction(key("Backspace"), true), "delete");
  assert.equal(editAction(key("Delete"), false), null); // nothing selected
  assert.equal(editAction(key("f"), true), null);
});

test("in a field its keys are the field's, but Ctrl-Z with nothing typed is the model's undo", () => {
  assert.equal(editAction(key("z", { ctrl: true, tag: "INPUT" }), true), null); // the field's own undo
  assert.equal(editAction(key("z", { ctrl: true, tag: "INPUT", untouchedInput: true }), true), "undo");
  assert.equal(editAction(key("Delete", { tag: "INPUT", untouchedInput: true }), true), null);
  assert.equal(editAction(key("Escape", { tag: "TEXTAREA" }), true), null);
});

test("the viewer's keys, not with a modifier nor in a field or on a button", () => {
  assert.equal(viewAction(key(" ")), "play");
  assert.equal(viewAction(key("f")), "fit");
  assert.equal(viewAction(key("l")), "follow");
  assert.equal(viewAction(key("f", { ctrl: true })), null);
  assert.equal(viewAction(key("f", { alt: true })), null);
  assert.equal(viewAction(key(" ", { tag: "BUTTON" })), null);
  assert.equal(viewAction(key("l", { tag: "SELECT" })), null);
  assert.equal(viewAction(key("x")), null);
});

test("zoom and pan by keys: + and - zoom, the arrows pan, not in a field", () => {
  assert.equal(viewAction(key("+")), "zoom-in");
  assert.equal(viewAction(key("=")), "zoom-in");
  assert.equal(viewAction(key("-")), "zoom-out");
  assert.equal(viewAction(key("ArrowLeft")), "pan-left");
  assert.equal(viewAction(key("ArrowDown", { tag: "g" })), "pan-down"); // a focused node of the diagram
  assert.equal(viewAction(key("ArrowUp", { tag: "INPUT" })), null);
  assert.equal(viewAction(key("-", { ctrl: true })), null); // the browser's own zoom
});
