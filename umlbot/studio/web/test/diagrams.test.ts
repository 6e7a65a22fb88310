import assert from "node:assert/strict";
import { test } from "node:test";
import { diagramIds, diagramInHash, firstDiagram, problemsIn } from "../src/features/diagrams/which";
import type { Diagnostic } from "../src/model/types";
import { twoDiagrams } from "./fixtures";

const problem = (file: string, severity: "error" | "warning" = "error"): Diagnostic => ({
  severity,
  message: "m",
  file,
  line: 1,
  column: 1,
  text: `${file}:1:1: ${severity}: m`,
});

test("the components come first, then the activities", () => {
  assert.deepEqual(diagramIds(twoDiagrams), ["components", "activity-main", "activity-other"]);
  assert.deepEqual(diagramIds(null), []);
});

test("the diagram shown: the address's, else the one shown before, else the first activity", () => {
  assert.equal(firstDiagram(twoDiagrams, "activity-other", "activity-main"), "activity-other");
  assert.equal(firstDiagram(twoDiagrams, "gone", "activity-other"), "activity-other");
  assert.equal(firstDiagram(twoDiagrams, "", ""), "activity-main");
  assert.equal(firstDiagram({ ...twoDiagrams, diagrams: [] }, "", ""), "components");
  assert.equal(diagramInHash("#diagram=activity-a%20b&x=1"), "activity-a b");
  assert.equal(diagramInHash(""), "");
});

test("a diagram's problems are those in its files (written relative or not)", () => {
  const list = [problem("/models/car/activities/main.yaml"), problem("activities/other.yaml", "warning")];
  assert.deepEqual(problemsIn(twoDiagrams.diagrams[0], list), [list[0]]);
  assert.deepEqual(problemsIn(twoDiagrams.diagrams[1], list), [list[1]]);
});
