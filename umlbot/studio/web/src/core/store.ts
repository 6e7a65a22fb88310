// The page's shared state: what more than one feature reads. Each field has one writer (named);
// the others read it. A change that others must act on is also said on the bus.

import { ModelIndex, StudioState } from "../model/state";
import type { Diagnostic, EditInfo, LayoutMap, Library, ModelView } from "../model/types";
import type { Selection } from "./selection";

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
  /** edit mode (null: the page only watches): from the first hello with `edit` (editing) */
  edit: EditSession | null = null;
}

export interface EditSession {
  /** the hello's (editing keeps `lane_files` and `empty` up to date) */
  info: EditInfo;
  /** the component library and node kinds (`GET /api/library`), once loaded (editing) */
  library: Library | null;
  /** the user's positions by diagram (editing from answers; connect while dragging) */
  positions: LayoutMap;
  /** what the properties panel shows (the feature that changes it draws the panel again) */
  selection: Selection;
}
