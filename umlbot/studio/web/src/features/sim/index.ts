// The sim panel: when the robot is the simulator's (a Run of the editor, `umlbot sim`), its track,
// the car and its sonar pings, drawn from the world frames the studio sends; beside the track the
// stereo camera's depth picture, from its component's state (docs/stereo.md).

import { $ } from "../../core/dom";
import type { Studio } from "../../core/studio";
import { DepthView } from "./depth";
import { SimPanel } from "./panel";

export function install({ bus, frames, store }: Studio): void {
  const sim = new SimPanel($<HTMLElement>("#sim"));
  const depth = new DepthView();
  // (a *Run* going on or ended draws its track: the world frame after the snapshot puts the car)
  bus.on("session.reset", (hello) => {
    sim.setTrack(hello.track ?? hello.edit?.run?.track ?? null);
    depth.attach(sim.body);
  });
  bus.on("server.run", (msg) => {
    if (msg.state !== "running") return;
    sim.setTrack(msg.track ?? null); // a new run: its track
    depth.attach(sim.body);
  });
  bus.on("frame.render", () => {
    const states: [string, unknown][] = [];
    for (const [name, c] of store.live.components) if (c.hasRetained) states.push([name, c.retained]);
    depth.draw(states);
  });
  bus.on("server.world", (msg) => {
    sim.push(msg);
    frames.schedule();
  });
  bus.on("frame.drawn", () => sim.flush());
}
