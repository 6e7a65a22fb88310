// Which files the compiler could not read as YAML, and where in a text a line and column are.
// Pure (test/textfix.test.ts).

import type { Diagnostic } from "../../model/types";

/** A model file the compiler could not read as YAML: the page shows its text to fix there. */
export interface BrokenFile {
  /** the file, relative to the model folder */
  file: string;
  line: number;
  column: number;
  /** the problem in words, without "invalid YAML: " */
  problem: string;
}

/** The files with a YAML syntax error, once each (its first problem), in the diagnostics' order. */
export function brokenFiles(list: Diagnostic[]): BrokenFile[] {
  const out: BrokenFile[] = [];
  for (const d of list) {
    if (d.severity !== "error" || !d.relpath || !d.message.startsWith("invalid YAML")) continue;
    if (out.some((b) => b.file === d.relpath)) continue;
    const problem = d.message.replace(/^invalid YAML:?\s*/, "") || "not valid YAML";
    out.push({ file: d.relpath, line: d.line, column: d.column, problem });
  }
  return out;
}

/** The character offset of 1-based `line` and `column` in `text` (clamped to the text). */
export function offsetOf(text: string, line: number, column: number): number {
  let at = 0;
  for (let l = 1; l < line; l++) {
    const nl = text.indexOf("\n", at);
    if (nl < 0) return text.length;
    at = nl + 1;
  }
  const end = text.indexOf("\n", at);
  const lineEnd = end < 0 ? text.length : end;
  return Math.min(at + Math.max(column - 1, 0), lineEnd);
}

/** The line numbers of the gutter: "1\n2\n…" for `text`. */
export function lineNumbers(text: string): string {
  const n = text.split("\n").length;
  return Array.from({ length: n }, (_, i) => String(i + 1)).join("\n");
}
