// umlbot studio page: the composition root. It makes the app's core (the bus, the store, the
// frame loop, the canvas) and installs the features; they talk through the bus and the store only
// (docs/architecture.md, "The studio's page"). Listeners of one event are called in this order:
// it matters for "frame.drawn" (the edit's timing, then follow, then the sim, then the latencies).

import { createStudio } from "./core/studio";
import { warmUp } from "./draw/layout";
import { install as calls } from "./features/calls";
import { install as connection } from "./features/connection";
import { install as diagnostics } from "./features/diagnostics";
import { install as diagrams } from "./features/diagrams";
import { install as editor } from "./features/editor";
import { install as follow } from "./features/follow";
import { install as keyboard } from "./features/keyboard";
import { install as live } from "./features/live";
import { install as navigate } from "./features/navigate";
import { install as replay } from "./features/replay";
import { install as session } from "./features/session";
import { install as sim } from "./features/sim";
import { install as status } from "./features/status";

const studio = createStudio();
for (const install of [
  connection,
  session,
  diagrams,
  diagnostics,
  calls,
  status,
  replay,
  navigate,
  keyboard,
  editor,
  follow,
  sim,
  live,
]) {
  install(studio);
}
warmUp();
studio.bus.emit("studio.start");
