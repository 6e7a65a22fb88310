import assert from "node:assert/strict";
import { test } from "node:test";
import { accept, offersAfter } from "../src/features/properties/completion";
import {
  fieldText,
  guardOf,
  newComponentName,
  nextLine,
  rangeText,
  readSetting,
  resolveSchema,
  typed,
} from "../src/features/properties/fields";
import type { ImplInfo, ModelNode } from "../src/model/types";
import { twoDiagrams } from "./fixtures";

test("a typed text is sent as a number or a boolean where the field takes one, else as text", () => {
  assert.equal(typed("value", " 42 ", undefined), 42);
  assert.equal(typed("speed", "-1.5", "number"), -1.5);
  assert.equal(typed("speed", "1.5", "string"), "1.5");
  assert.equal(typed("value", "true", "any"), true);
  assert.equal(typed("call", "12", "number"), "12"); // a call is text
  assert.equal(typed("value", "  ", undefined), null); // nothing: unset
});

test("a settings schema's references and optional types are resolved", () => {
  const root = { $defs: { Pin: { type: "integer", minimum: 0, maximum: 27 } } };
  const pin = resolveSchema({ $ref: "#/$defs/Pin", description: "the pin" }, root);
  assert.equal(pin.type, "integer");
  assert.equal(pin.maximum, 27);
  assert.equal(pin.description, "the pin");
  const optional = resolveSchema({ anyOf: [{ type: "null" }, { type: "number", minimum: 1 }] }, root);
  assert.equal(optional.type, "number");
  assert.equal(optional.minimum, 1);
  assert.equal(rangeText(pin), "0..27");
  assert.equal(rangeText(optional), "≥ 1");
  assert.equal(rangeText({ maximum: 5 }), "≤ 5");
  assert.equal(rangeText({}), "");
});

test("a setting's field is checked against its schema before anything is sent", () => {
  const pin = { type: "integer", minimum: 0, maximum: 27 };
  assert.deepEqual(readSetting("5", "", pin, "integer", true, true), { ok: true, value: 5 });
  assert.deepEqual(readSetting("", "", pin, "integer", true, true), { ok: false, why: "is required" });
  assert.deepEqual(readSetting("", "", pin, "integer", false, false), { ok: true });
  assert.deepEqual(readSetting("30", "", pin, "integer", true, true), { ok: false, why: "must be 0..27" });
  assert.deepEqual(readSetting("1.5", "", pin, "integer", true, true), {
    ok: false,
    why: "must be a whole number, 0..27",
  });
  assert.deepEqual(readSetting("x", "", { type: "number", minimum: 1 }, "number", true, true), {
    ok: false,
    why: "must be a number",
  });
  assert.deepEqual(readSetting("0", "", { minimum: 1 }, "number", true, true), {
    ok: false,
    why: "must be at least 1",
  });
  // an unchanged default is not written; a kept one is
  assert.deepEqual(readSetting("7", "7", pin, "integer", false, false), { ok: true });
  assert.deepEqual(readSetting("7", "7", pin, "integer", false, true), { ok: true, value: 7 });
  assert.deepEqual(readSetting("[1, 2]", "", {}, "array", false, true), { ok: true, value: [1, 2] });
  assert.deepEqual(readSetting("{", "", {}, "object", false, true), { ok: false, why: "must be JSON ({})" });
  assert.deepEqual(readSetting(" left ", "", {}, "string", false, true), { ok: true, value: "left" });
});

test("a node's field as written, a decision's guards, the lines a node's problems are on", () => {
  const decision: ModelNode = {
    id: "d",
    kind: "decision",
    label: "d",
    line: 4,
    // biome-ignore lint/suspicious/noThenProperty: a decision's branch in the model format is {if, then}
    fields: { branches: [{ if: "x > 0", then: "a" }, { else: "b" }], timeout: 5 },
  };
  assert.equal(guardOf(decision, { id: "1", source: "d", target: "a", label: "x > 0" }), "x > 0");
  assert.equal(guardOf(decision, { id: "2", source: "d", target: "b", label: "" }), "else");
  assert.equal(guardOf(decision, { id: "3", source: "d", target: "c", label: "lbl", guard: "g" }), "g");
  assert.equal(fieldText(decision, "timeout"), "5");
  assert.equal(fieldText(decision, "missing"), "");
  // an older model view without fields: from the label
  assert.equal(fieldText({ id: "a", kind: "action", label: "M.go()", line: 1 }, "call"), "M.go()");
  const lane = twoDiagrams.diagrams[0].lanes[0];
  assert.equal(nextLine(lane, lane.nodes[0]), 4);
  assert.equal(nextLine(lane, lane.nodes[2]), Infinity);
});

test("a new component is named after its first free seed, else its kind and a number", () => {
  const impl = { id: "hc_sr04", kind: "sonar", aliases: ["Sonar", "FrontSonar"] } as unknown as ImplInfo;
  assert.equal(newComponentName(impl, new Set()), "Sonar");
  assert.equal(newComponentName(impl, new Set(["Sonar"])), "FrontSonar");
  assert.equal(newComponentName(impl, new Set(["Sonar", "FrontSonar", "Sonar1"])), "Sonar2");
});

test("a completion replaces the word being typed, or the range the server names", () => {
  const item = { label: "forward", kind: "feature", insert: "forward(" };
  assert.deepEqual(accept("Motor.fo", 8, item), { value: "Motor.forward(", at: 14 });
  // the rest of the word after the cursor goes too
  assert.deepEqual(accept("Motor.fox + 1", 8, item), { value: "Motor.forward( + 1", at: 14 });
  assert.deepEqual(accept("Motor.fo", 8, item, [0, 8]), { value: "forward(", at: 8 });
  assert.deepEqual(accept("", 0, { label: "Motor", kind: "component" }), { value: "Motor", at: 5 });
  assert.ok(offersAfter("Motor."));
  assert.ok(!offersAfter("Motor.go() "));
  assert.ok(!offersAfter("x > 10"));
  assert.ok(!offersAfter("s == 'a'"));
});
