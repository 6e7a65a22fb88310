// Which notice may replace the one shown. Pure (test/notices.test.ts).

/** Notices that wait for the user's decision (their buttons are the way out). */
const DECISION_NOTICES = new Set(["conflict", "recovery"]);
/** Notices that only pass by: a run's, a hint. */
const PASSING_NOTICES = new Set(["run", "run-goal", "run-ended", "run-stopped", "hint"]);

/** A notice of `kind` may be shown in place of the one shown (`shown`: its kind, null when none
 * is): a passing notice never replaces one that waits for the user's decision (a conflict with the
 * disk, unsaved edits kept at quit). */
export function mayShow(kind: string, shown: string | null): boolean {
  return !(PASSING_NOTICES.has(kind) && shown !== null && DECISION_NOTICES.has(shown));
}

/** What the close button of a notice of `kind` says: closing hides it, and never undoes, discards
 * or saves anything. */
export function closeWords(kind: string): { label: string; title: string; aria: string } {
  return kind === "recovery"
    ? {
        label: "Decide later",
        title:
          "Hide this notice: the kept edits stay in the recovery file, unrestored and not discarded; the next start of the studio offers them again",
        aria: "Decide later",
      }
    : { label: "×", title: "Hide this notice (nothing is undone)", aria: "Hide this notice" };
}
