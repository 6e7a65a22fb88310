// Run and Stop: the edited model runs in the simulator on the chosen track and speed; the page
// watches it as it watches a robot, and says how the run ended.

import { $, el } from "../../core/dom";
import type { Studio } from "../../core/studio";
import type { RunMsg } from "../../model/types";
import { runEndText, speedWords, standStillText } from "./text";

export function install({ bus, store, api }: Studio): void {
  const runBtn = $<HTMLButtonElement>("#run");
  const stopBtn = $<HTMLButtonElement>("#stop");
  const trackSel = $<HTMLSelectElement>("#track");
  const speedSel = $<HTMLSelectElement>("#run-speed");

  const setRunning = (running: boolean): void => {
    runBtn.dataset.running = String(running);
    stopBtn.disabled = !running;
  };

  const loadTracks = async (): Promise<void> => {
    try {
      const res = await fetch("/api/tracks");
      const data = (await res.json()) as { tracks: ({ name: string; title?: string } | string)[] };
      trackSel.replaceChildren();
      for (const t of data.tracks ?? []) {
        const name = typeof t === "string" ? t : t.name;
        el("option", { value: name }, trackSel, typeof t === "string" ? t : (t.title ?? t.name));
      }
    } catch (exc) {
      console.error("studio: no tracks", exc);
    }
  };

  const run = async (): Promise<void> => {
    await bus.request("edit.settle");
    const speed = Number(speedSel.value) || 2;
    const a = await api.request<{ running?: boolean; error?: string }>("/api/run", { track: trackSel.value, speed });
    if (!a) return;
    setRunning(true);
    bus.emit("live.reset");
    bus.emit("follow.set", true); // a run is to be watched: Follow turned off by clicking comes back on
    bus.request("notice.show", {
      kind: "run",
      text: `Running the edited model in the simulator on ${trackSel.value} at ${speed}× (${speedWords(speed)}).`,
      hideAfterMs: 4000,
    });
  };

  const stop = async (): Promise<void> => {
    await api.request("/api/stop", {});
    setRunning(false);
  };

  /** A run started or ended. `again`: the hello repeats a run that ended already (a reload): its
   * end was said once (the browser's storage remembers). */
  const onRun = (msg: RunMsg, again = false): void => {
    setRunning(msg.running ?? msg.state === "running");
    const r = msg.result;
    const key = `umlbot-studio-run-end:${store.edit!.info.token}`;
    const stamp = JSON.stringify(r ?? null);
    if (msg.state === "ended" && r && again) {
      let seen = false;
      try {
        seen = localStorage.getItem(key) === stamp;
      } catch {
        /* no storage: say it */
      }
      if (seen) return;
    }
    const stood = r ? standStillText(r) : "";
    const kind = stood ? "run-stopped" : r?.goal_reached ? "run-goal" : "run-ended";
    // why the car stood still stays until it is closed: it is what the run is to be read for
    const notice = {
      kind,
      text: r ? `${runEndText(r)}${stood ? ` ${stood}` : ""}` : "",
      hideAfterMs: stood ? 0 : 10000,
    };
    if (msg.state === "ended" && r && bus.request("notice.show", notice)) {
      try {
        localStorage.setItem(key, stamp); // said: a reload does not say it again
      } catch {
        /* no storage */
      }
    }
  };

  runBtn.onclick = () => void run();
  stopBtn.onclick = () => void stop();
  bus.on("edit.started", () => void loadTracks());
  bus.on("server.run", (msg) => {
    if (store.edit) onRun(msg);
  });
  bus.on("edit.after-hello", (info) => {
    if (info.run) onRun({ type: "run", state: info.run.running ? "running" : "ended", ...info.run }, true);
  });
}
