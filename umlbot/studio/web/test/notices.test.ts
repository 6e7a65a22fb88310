import assert from "node:assert/strict";
import { test } from "node:test";
import { closeWords, mayShow } from "../src/features/notices/policy";

test("a passing notice never replaces one that waits for the user's decision", () => {
  assert.ok(!mayShow("run-ended", "conflict"));
  assert.ok(!mayShow("hint", "recovery"));
  assert.ok(mayShow("hint", null)); // none shown
  assert.ok(mayShow("hint", "saved"));
  // a decision, an error or a result replaces anything
  assert.ok(mayShow("conflict", "recovery"));
  assert.ok(mayShow("error", "conflict"));
  assert.ok(mayShow("reloaded", "conflict"));
});

test("closing a notice of kept edits says it decides nothing", () => {
  assert.equal(closeWords("recovery").label, "Decide later");
  assert.match(closeWords("recovery").title, /unrestored and not discarded/);
  assert.deepEqual(closeWords("error"), {
    label: "×",
    title: "Hide this notice (nothing is undone)",
    aria: "Hide this notice",
  });
});
