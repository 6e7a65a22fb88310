// umlbot studio page: the composition root. It makes the app's core (the bus, the store, the
// frame loop, the canvas, the HTTP API) and installs the features; they talk through the bus and
// the store only (docs/architecture.md, "The studio's page"). Listeners of one event are called in
// the order of this list; it matters for "frame.drawn" (the edit's timing, then follow, the sim,
// the latencies), "edit.after-hello" (a run's end is said before a conflict replaces it) and
// "model.missing" (the new-model form, then the palette).

import { createStudio, type Feature } from "./core/studio";
import { warmUp } from "./draw/layout";
import { install as calls } from "./features/calls";
import { install as connect } from "./features/connect";
import { install as connection } from "./features/connection";
import { install as diagnostics } from "./features/diagnostics";
import { install as diagrams } from "./features/diagrams";
import { install as editing } from "./features/editing";
import { install as fleet } from "./features/fleet";
import { install as follow } from "./features/follow";
import { install as history } from "./features/history";
import { install as keyboard } from "./features/keyboard";
import { install as live } from "./features/live";
import { install as navigate } from "./features/navigate";
import { install as newModel } from "./features/new-model";
import { install as notices } from "./features/notices";
import { install as palette } from "./features/palette";
import { install as properties } from "./features/properties";
import { install as regions } from "./features/regions";
import { install as replay } from "./features/replay";
import { install as run } from "./features/run";
import { install as save } from "./features/save";
import { install as selection } from "./features/selection";
import { install as session } from "./features/session";
import { install as sim } from "./features/sim";
import { install as status } from "./features/status";
import { install as textfix } from "./features/textfix";

const features: Feature[] = [
  // watching
  connection,
  fleet,
  session,
  regions, // before diagrams: an edit inside a collapsed region opens it before the redraw
  diagrams,
  diagnostics,
  calls,
  status,
  replay,
  navigate,
  keyboard,
  // editing
  editing,
  notices,
  selection,
  connect,
  properties,
  history,
  run,
  save,
  newModel,
  palette,
  textfix,
  // after a frame's drawing, in this order
  follow,
  sim,
  live,
];
const studio = createStudio();
for (const install of features) install(studio);
warmUp();
studio.bus.emit("studio.start");
