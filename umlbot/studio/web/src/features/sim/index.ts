// The sim panel: when the robot is the simulator's (a Run of the editor, `umlbot sim`), its track,
// the car and its sonar pings, drawn from the world frames the studio sends.

import { $ } from "../../core/dom";
import type { Studio } from "../../core/studio";
import { SimPanel } from "./panel";

export function install({ bus, frames }: Studio): void {
  const sim = new SimPanel($<HTMLElement>("#sim"));
  // (a *Run* going on or ended draws its track: the world frame after the snapshot puts the car)
  bus.on("session.reset", (hello) => sim.setTrack(hello.track ?? hello.edit?.run?.track ?? null));
  bus.on("server.run", (msg) => {
    if (msg.state === "running") sim.setTrack(msg.track ?? null); // a new run: its track
  });
  bus.on("server.world", (msg) => {
    sim.push(msg);
    frames.schedule();
  });
  bus.on("frame.drawn", () => sim.flush());
}
