// The toolbar's status: the orchestrator's state, what was lost on the way (gaps in the stream,
// events the server dropped, trace events lost), the studio's connection to the broker; and, under
// the legend, which clock the figures on the nodes and in the Calls panel are in.

import { $ } from "../../core/dom";
import type { Studio } from "../../core/studio";
import { BrokerPill } from "./broker";
import { clockNote, type Gaps, gapsText, orchestratorText } from "./text";

export function install({ bus, store }: Studio): void {
  const orchEl = $<HTMLElement>("#orchestrator-status");
  const gapsEl = $<HTMLElement>("#gaps");
  const clockEl = $<HTMLElement>("#clock-note");
  const broker = new BrokerPill();
  let sim = false;
  const drawClock = (): void => {
    const note = clockNote(store.mode, sim);
    clockEl.textContent = note.text;
    clockEl.title = note.title;
    clockEl.dataset.clock = store.mode === "replay" ? "trace" : sim ? "sim" : "robot";
  };
  const counts = { gaps: 0, lostFrames: 0, dropped: 0 };
  let expectSeq = 0;

  const drawGaps = (): void => {
    const gaps: Gaps = { ...counts, lostTrace: store.live.traceLost };
    gapsEl.dataset.gaps = String(gaps.gaps);
    gapsEl.dataset.lostFrames = String(gaps.lostFrames);
    gapsEl.dataset.dropped = String(gaps.dropped);
    gapsEl.dataset.lostTrace = String(gaps.lostTrace);
    const text = gapsText(gaps);
    gapsEl.hidden = text === "";
    gapsEl.textContent = text;
  };

  const drawOrchestrator = (): void => {
    const text = orchestratorText(store.live.orch, store.live.exitPayload);
    orchEl.dataset.state = store.live.orch.state;
    orchEl.textContent = text;
    orchEl.title = text; // the pill may be cut short: the whole text on hover
  };

  bus.on("session.reset", (hello) => {
    expectSeq = 0;
    counts.gaps = 0;
    counts.lostFrames = 0;
    counts.dropped = 0;
    broker.reset(!!hello.edit?.run?.running);
    sim = !!(hello.track || hello.edit?.run);
    drawClock();
  });
  bus.on("server.events", (msg) => {
    if (expectSeq && msg.seq !== expectSeq) {
      counts.gaps += 1;
      if (msg.seq > expectSeq) counts.lostFrames += msg.seq - expectSeq;
    }
    expectSeq = msg.seq + 1;
    counts.dropped += msg.dropped ?? 0;
    if (store.mode === "live") for (const e of msg.events) if (e.type === "broker") broker.show(e);
  });
  bus.on("server.run", (msg) => {
    broker.setRunActive(msg.state === "running");
    if (msg.state === "running" && !sim) {
      sim = true; // a Run of the editor: the figures are the simulated car's from now on
      drawClock();
    }
  });
  bus.on("frame.render", (full) => {
    if (!store.live.dirtyOrch && !full) return;
    drawOrchestrator();
    drawGaps();
  });
  drawGaps();
  drawClock();
}
