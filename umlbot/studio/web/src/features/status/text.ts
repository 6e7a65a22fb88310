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

/** Which clock the figures are in: the nodes' durations (from the trace events' own start and end)
 * and the Calls panel's latencies (request to reply, as the studio saw them). `sim`: the robot is
 * the simulator's (`umlbot sim --studio`, a Run of the editor), whose nodes run on simulated time. */
export function clockNote(mode: "live" | "replay", sim: boolean): { text: string; title: string } {
  if (mode === "replay") {
    return {
      text: "node times: the recorded run's clock",
      title:
        "The durations under the nodes and the Calls panel's latencies are those the trace recorded: " +
        "simulated time when it was recorded in the simulator, the robot's clock otherwise.",
    };
  }
  if (sim) {
    return {
      text: "node times: simulated time · calls: wall clock",
      title:
        "The durations under the nodes are the simulated car's time, the same at any run speed: a call " +
        "to a simulated part takes none of it (0 ms), a msleep(1500) takes 1.5 s. The Calls panel's " +
        "latencies are wall-clock milliseconds, as the studio saw each request and its reply.",
    };
  }
  return {
    text: "node times: the robot's clock · calls: wall clock",
    title:
      "The durations under the nodes come from the robot's own trace (start to end of each node); the " +
      "Calls panel's latencies are wall-clock milliseconds, as the studio saw each request and its reply.",
  };
}
