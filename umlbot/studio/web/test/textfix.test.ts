import assert from "node:assert/strict";
import { test } from "node:test";
import { brokenFiles, lineNumbers, offsetOf } from "../src/features/textfix/find";
import type { Diagnostic } from "../src/model/types";

const yamlError = (relpath: string, line: number, message: string): Diagnostic => ({
  severity: "error",
  message,
  file: `/m/${relpath}`,
  line,
  column: 6,
  text: `/m/${relpath}:${line}:6: error: ${message}`,
  relpath,
});

test("a file that is not valid YAML is listed once, with its first problem in words", () => {
  const list = [
    yamlError("activities/broken.yaml", 4, "invalid YAML: did not find expected ',' or '}'"),
    yamlError("activities/broken.yaml", 9, "invalid YAML: later"),
    { ...yamlError("activities/main.yaml", 3, "unknown node kind 'stat'") },
  ];
  assert.deepEqual(brokenFiles(list), [
    { file: "activities/broken.yaml", line: 4, column: 6, problem: "did not find expected ',' or '}'" },
  ]);
  assert.deepEqual(brokenFiles([{ ...list[0], severity: "warning" }]), []);
});

test("line and column find their place in the text, clamped to its line", () => {
  const text = "lane: A\nnodes:\n  - {id: a\n";
  assert.equal(offsetOf(text, 1, 1), 0);
  assert.equal(text.slice(offsetOf(text, 3, 5)), "{id: a\n");
  assert.equal(offsetOf(text, 2, 99), text.indexOf("\n  -")); // past its end: the end of the line
  assert.equal(offsetOf(text, 99, 1), text.length);
  assert.equal(lineNumbers("a\nb\nc"), "1\n2\n3");
});
