// The page's shared state: what more than one feature reads. Each field has one writer (named);
// the others read it. A change that others must act on is also said on the bus.

import { ModelIndex, StudioState } from "../model/state";
import type { Diagnostic, ModelView } from "../model/types";

export class Store {
  /** live events or a recorded run (session: from the hello) */
  mode: "live" | "replay" = "live";
  /** the robot id the studio follows (session) */
  robot = "";
  /** the model shown; null: none, or it does not compile (diagrams) */
  model: ModelView | null = null;
  /** the shown model's lanes and flows, indexed (diagrams; live at a new session) */
  index = new ModelIndex(null);
  /** the view state the drawing shows: counts, trails, calls (live replaces it for a new session
   * or run; replay moves it through the recording; the drawing and the panels read it) */
  live = new StudioState(this.index);
  /** the compiler's problems with the model shown (diagnostics) */
  diagnostics: Diagnostic[] = [];
  /** lane name -> the id of the diagram that draws it (diagrams) */
  laneDiagram = new Map<string, string>();
}
