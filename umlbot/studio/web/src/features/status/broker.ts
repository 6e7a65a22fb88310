// The studio's own connection to the broker (not the page's socket to the studio): without it the
// page can show nothing of the robot, so the pill says why and when the next attempt is. While a
// Run of the editor goes on, it shows the connection to that run's own broker (the simulator's),
// reported like the robot's; after the run, the robot's broker again.

import { $ } from "../../core/dom";
import type { MonitorEvent } from "../../model/types";
import { brokerView } from "./text";

interface Seen {
  e: MonitorEvent;
  retryAt: number;
}

export class BrokerPill {
  private el = $<HTMLElement>("#broker-status");
  private robot: Seen | null = null;
  private run: Seen | null = null;
  private runActive = false;
  private timer = 0;

  /** A new session: hidden until the broker source says how its connection is. */
  reset(runActive: boolean): void {
    this.el.hidden = true;
    this.robot = null;
    this.run = null;
    this.runActive = runActive;
  }

  show(e: MonitorEvent): void {
    const seen = { e, retryAt: e.retry_in_s !== undefined ? performance.now() + e.retry_in_s * 1000 : 0 };
    if (e.source === "run") this.run = seen;
    else this.robot = seen;
    this.draw();
  }

  /** A Run started or ended: the pill shows whose broker connection is relevant now. */
  setRunActive(active: boolean): void {
    this.runActive = active;
    if (active) this.run = null; // this run's broker, not the last run's
    this.draw();
  }

  private draw(): void {
    const run = this.runActive && this.run !== null;
    const seen = run ? this.run : this.robot;
    const connected = !!seen?.e.connected || !!seen?.e.ended; // (ended: nothing is retried)
    // while it is not connected the pill counts down to the next attempt, every second
    if (!connected && seen && !this.timer) this.timer = window.setInterval(() => this.draw(), 1000);
    if ((connected || !seen) && this.timer) {
      window.clearInterval(this.timer);
      this.timer = 0;
    }
    const el = this.el;
    el.dataset.source = run ? "run" : "robot";
    if (!seen) {
      el.hidden = true;
      return;
    }
    const view = brokerView(seen.e, run, seen.retryAt, performance.now());
    el.hidden = false;
    el.dataset.state = view.state;
    el.textContent = view.text;
    el.title = view.title;
  }
}
