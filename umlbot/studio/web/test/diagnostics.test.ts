import assert from "node:assert/strict";
import { test } from "node:test";
import { changedMarks, nodeAtLine, nodeNamed, strongerMark } from "../src/features/diagnostics/locate";
import { ModelIndex } from "../src/model/state";
import type { Diagnostic } from "../src/model/types";
import { twoDiagrams } from "./fixtures";

const laneDiagram = new Map([
  ["A", "activity-main"],
  ["B", "activity-main"],
  ["C", "activity-other"],
]);

test("a problem at file:line is its node's whose first line is the last at or before it", () => {
  const at = (file: string, line: number): string => {
    const n = nodeAtLine(twoDiagrams, file, line);
    return n ? `${n.diagram} ${n.lane}/${n.node}` : "";
  };
  assert.equal(at("/x/activities/main.yaml", 5), "activity-main A/a");
  assert.equal(at("activities/main.yaml", 14), "activity-main B/a");
  assert.equal(nodeAtLine(twoDiagrams, "activities/main.yaml", 1), null); // the lane's own line
  assert.equal(nodeAtLine(twoDiagrams, "deployment.yaml", 5), null);
});

test("a node the server names is found when it is drawn", () => {
  const index = new ModelIndex(twoDiagrams);
  assert.deepEqual(nodeNamed(laneDiagram, index, "C", "end"), { diagram: "activity-other", lane: "C", node: "end" });
  assert.equal(nodeNamed(laneDiagram, index, "C", "nope"), null);
  assert.equal(nodeNamed(laneDiagram, index, "Z", "end"), null);
  assert.equal(nodeNamed(laneDiagram, index, "C", ""), null);
});

test("an error outranks a warning on a node; only changed marks are drawn again", () => {
  const d = (severity: "error" | "warning", text: string): Diagnostic => ({
    severity,
    message: text,
    file: "f",
    line: 1,
    column: 1,
    text,
  });
  const w = strongerMark(undefined, d("warning", "w"));
  assert.deepEqual(w, { level: "warning", message: "w" });
  assert.deepEqual(strongerMark(w, d("error", "e")), { level: "error", message: "e" });
  assert.deepEqual(strongerMark({ level: "error", message: "e" }, d("warning", "w")), { level: "error", message: "e" });
  assert.deepEqual(strongerMark({ level: "error", message: "e1" }, d("error", "e2")), {
    level: "error",
    message: "e1",
  });
  const before = new Map([
    ["same", { level: "error" as const, message: "x" }],
    ["changed", { level: "warning" as const, message: "x" }],
    ["gone", { level: "error" as const, message: "x" }],
  ]);
  const after = new Map([
    ["same", { level: "error" as const, message: "x" }],
    ["changed", { level: "error" as const, message: "x" }],
    ["new", { level: "warning" as const, message: "y" }],
  ]);
  assert.deepEqual(changedMarks(before, after).sort(), ["changed", "gone", "new"]);
});
