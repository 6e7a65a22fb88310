// Replay a recorded run (`umlbot studio --replay`): play, pause, speed and a time slider; space
// plays or pauses. The view state is moved through the recording (timeline.ts); the drawing and
// the panels show it as they show live events.

import { $ } from "../../core/dom";
import type { Studio } from "../../core/studio";
import type { MonitorEvent } from "../../model/types";
import { buildTimeline, seek, type Timeline } from "./timeline";

interface Replay {
  tl: Timeline;
  playing: boolean;
  prevTs: number;
}

export function install({ bus, store, hooks, frames }: Studio): void {
  const replayEl = $<HTMLElement>("#replay");
  const notesEl = $<HTMLElement>("#replay-notes");
  const playBtn = $<HTMLButtonElement>("#replay-play");
  const speedSel = $<HTMLSelectElement>("#replay-speed");
  const timeInput = $<HTMLInputElement>("#replay-time");
  const clockEl = $<HTMLElement>("#replay-clock");
  let replay: Replay | null = null;

  const moveTo = (t: number): void => {
    if (!replay) return;
    const { tl } = replay;
    const traces = seek(tl, store.live, t);
    if (traces) {
      hooks.applied += traces;
      bus.emit("follow.due");
    }
    if (document.activeElement !== timeInput || replay.playing) timeInput.value = tl.time.toFixed(3);
    clockEl.textContent = `${tl.time.toFixed(3)} s / ${tl.duration.toFixed(3)} s`;
    frames.schedule();
  };

  const updatePlay = (): void => {
    const playing = !!replay?.playing;
    playBtn.textContent = playing ? "❚❚ Pause" : "▶ Play";
    playBtn.setAttribute("aria-pressed", String(playing));
  };

  const setup = (events: MonitorEvent[], notes: string[]): void => {
    notesEl.hidden = notes.length === 0;
    notesEl.textContent = notes.map((n) => `⚠ ${n}`).join("  ");
    notesEl.title = notes.join("\n");
    const tl = buildTimeline(events, store.live);
    replay = { tl, playing: false, prevTs: 0 };
    timeInput.min = "0";
    timeInput.max = tl.duration.toFixed(3);
    timeInput.step = "0.001";
    replayEl.hidden = false;
    moveTo(0);
    updatePlay();
  };

  /** The replay's clock advances with the frames, at the chosen speed. */
  const tick = (ts: number): void => {
    const r = replay;
    if (store.mode !== "replay" || !r?.playing) return;
    if (r.prevTs) {
      const speed = Number(speedSel.value) || 1;
      const t = r.tl.time + ((ts - r.prevTs) / 1000) * speed;
      if (t >= r.tl.duration) {
        r.playing = false;
        updatePlay();
      }
      moveTo(t);
    }
    r.prevTs = ts;
  };

  playBtn.addEventListener("click", () => {
    if (!replay) return;
    if (!replay.playing && replay.tl.time >= replay.tl.duration) moveTo(0);
    replay.playing = !replay.playing;
    replay.prevTs = 0;
    updatePlay();
    frames.schedule();
  });
  timeInput.addEventListener("input", () => {
    if (!replay) return;
    moveTo(Number(timeInput.value));
    frames.render(); // a scrub shows its moment at once, not a frame later
  });

  bus.on("session.reset", () => {
    replay = null;
    replayEl.hidden = true;
  });
  bus.on("session.started", (hello) => {
    if (store.mode === "replay") setup(hello.replay?.events ?? [], hello.replay?.notes ?? []);
  });
  bus.on("replay.toggle", () => {
    if (!replay) return undefined;
    playBtn.click();
    return true;
  });
  bus.on("frame.apply", tick);
  bus.on("frame.flowing", () => (replay?.playing ? true : undefined));
  bus.on("frame.busy", () => (replay?.playing ? true : undefined));
}
