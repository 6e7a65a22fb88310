// What the toolbar's status pills say: the orchestrator's state, the gaps in the stream, the
// studio's connection to the broker. Pure (test/status.test.ts).

import { jsonText } from "../../model/format";
import type { MonitorEvent } from "../../model/types";

/** The orchestrator pill: its state, detail and exit payload. */
export function orchestratorText(orch: { state: string; detail: string }, exitPayload: unknown): string {
  let text = `orchestrator: ${orch.state}`;
  if (orch.detail) text += ` — ${orch.detail}`;
  if (exitPayload !== undefined) text += ` · exit ${jsonText(exitPayload)}`;
  return text;
}

export interface Gaps {
  /** gaps in the frames' sequence numbers */
  gaps: number;
  /** frames lost in them */
  lostFrames: number;
  /** events the server dropped for this page */
  dropped: number;
  /** trace events lost (gaps in their sequence numbers) */
  lostTrace: number;
}

/** What was lost on the way, in words ("" when nothing was). */
export function gapsText({ gaps, lostFrames, dropped, lostTrace }: Gaps): string {
  const parts: string[] = [];
  if (gaps) {
    parts.push(
      `${gaps} gap${gaps === 1 ? "" : "s"} in the stream (${lostFrames} frame${lostFrames === 1 ? "" : "s"} lost)`,
    );
  }
  if (dropped) parts.push(`${dropped} events dropped by the server`);
  if (lostTrace) parts.push(`${lostTrace} trace events lost`);
  return parts.length ? `⚠ ${parts.join(" · ")}` : "";
}

/** The broker pill for broker event `e`: `run`: the broker of the editor's Run (the simulator's);
 * `retryAt`, `now`: when the next attempt is, and now (performance.now() ms). */
export function brokerView(
  e: MonitorEvent,
  run: boolean,
  retryAt: number,
  now: number,
): { state: string; text: string; title: string } {
  const who = run ? "sim broker" : "broker";
  if (e.connected) {
    return {
      state: "connected",
      text: `${who} connected`,
      title: run
        ? `connected to the simulator's own broker of this run (${e.url ?? ""})`
        : `connected to ${e.url ?? "the broker"}`,
    };
  }
  if (e.ended) {
    // a simulated run's broker closed with the run: nothing is wrong, nothing is retried
    return { state: "ended", text: `${who}: the run has ended`, title: `${e.url ?? "the broker"}: ${e.ended}` };
  }
  let text = `${who} ${e.url ?? ""}: ${e.problem ?? "connecting…"}`;
  if (e.problem) {
    const left = Math.max(0, Math.ceil((retryAt - now) / 1000));
    text += left > 0 ? `, retrying in ${left} s` : ", retrying…";
    if ((e.attempts ?? 0) > 1) text += ` (attempt ${e.attempts})`;
  }
  return { state: e.problem ? "failed" : "connecting", text, title: text }; // the toolbar may cut it short
}
