// Every event of the page's bus, with its payload: the one list of how the features talk.
// A notification (`bus.emit`) says what happened and every listener hears it; a request
// (`bus.request`, an answer type other than void) is answered by the first listener that returns
// something. Listeners are called in the order main.ts installs the features.

import type { Positions } from "../draw/layout";
import type {
  ConflictMsg,
  Diagnostic,
  EditAnswer,
  EditInfo,
  EventsMsg,
  FilesMsg,
  HelloMsg,
  ModelDiagram,
  ModelMsg,
  ModelView,
  Op,
  RobotMsg,
  RunMsg,
  WorldMsg,
} from "../model/types";
import type { EventBus } from "./bus";

export interface StudioEvents {
  /** every feature is installed: the page may connect */
  "studio.start": () => void;

  // ---- what the studio sent (connection), one event per message type (docs/studio.md)
  "server.hello": (msg: HelloMsg) => void;
  "server.events": (msg: EventsMsg) => void;
  "server.world": (msg: WorldMsg) => void;
  "server.files": (msg: FilesMsg) => void;
  "server.conflict": (msg: ConflictMsg) => void;
  "server.run": (msg: RunMsg) => void;
  "server.robot": (msg: RobotMsg) => void;
  "server.model": (msg: ModelMsg) => void;

  // ---- the session (a hello starts one)
  /** a new session: forget the previous one's state (`shown`: the model the hello draws) */
  "session.reset": (hello: HelloMsg, shown: ModelView | null) => void;
  /** the hello's model is shown: start what needs it (a replay) */
  "session.started": (hello: HelloMsg) => void;
  /** ask the studio for a fresh hello (its working copy) by connecting again */
  "session.resync": () => void;
  /** a new run (or robot): forget the previous run's counts */
  "live.reset": () => void;

  // ---- the model and its diagrams
  /** show a model (null: none) with its problems; `fromEditor`: the editor's own answer */
  "model.set": (model: ModelView | null, diagnostics: Diagnostic[], fromEditor: boolean) => void;
  /** an edit's answer: show it, or keep the last good drawing when it does not compile */
  "model.edited": (model: ModelView | null, diagnostics: Diagnostic[]) => void;
  /** draw the model again (the user's positions changed) */
  "model.relayout": () => void;
  /** a model is shown (its diagrams are being drawn) */
  "model.shown": (model: ModelView) => void;
  /** there is no model to show: `message` is the canvas's message box */
  "model.missing": (message: HTMLElement) => void;
  /** show the diagram `id` */
  "diagram.select": (id: string) => void;
  /** the user turned to diagram `id` (the editor's panels follow) */
  "diagram.shown": (id: string) => void;
  /** the problems to list and mark */
  "diagnostics.set": (list: Diagnostic[]) => void;
  /** the problems listed now */
  "diagnostics.changed": (list: Diagnostic[]) => void;
  /** open the text of model file `file` (relative path) at `line`:`column`, that line marked with
   * `problem` (a file that cannot be read as YAML: its first problem, to fix it there) */
  "file.show": (file: string, line?: number, column?: number, problem?: string) => void;

  // ---- the view
  "view.fit": () => void;
  /** pan the shown diagram by (dx, dy) screen px (keys: the arrows) */
  "view.pan": (dx: number, dy: number) => void;
  /** zoom the shown diagram by `factor` about the canvas's centre (keys: + and -) */
  "view.zoom": (factor: number) => void;
  /** centre a node at a readable zoom, and flash it */
  "view.reveal": (lane: string, node: string) => void;
  "follow.set": (on: boolean) => void;
  "follow.toggle": () => void;
  /** nodes ran, or the view changed: follow looks again */
  "follow.due": () => void;
  /** a press on the canvas: true when a feature took it (no panning) */
  "canvas.press": (ev: PointerEvent) => boolean | undefined;
  /** Enter or space on a focused element of the canvas (a node, a lane's header, a component):
   * true when a feature took it */
  "canvas.activate": (el: Element) => boolean | undefined;
  /** focus the selected element of the shown diagram (else the canvas) */
  "canvas.focus-selection": () => void;
  /** play or pause the replay: true when there is one */
  "replay.toggle": () => true | undefined;

  // ---- the frame loop (core/frames.ts)
  /** true when events flow (frame times are recorded, and frames go on) */
  "frame.flowing": () => true | undefined;
  "frame.apply": (ts: number) => void;
  /** the view state's changes are drawn: the panels' turn (`full`: everything changed) */
  "frame.render": (full: boolean) => void;
  "frame.drawn": () => void;
  /** true when a feature needs another frame */
  "frame.busy": () => true | undefined;

  // ---- edit mode
  /** a hello in edit mode (before its model is shown) */
  "edit.hello": (info: EditInfo) => void;
  /** the first hello in edit mode set edit mode up (store.edit): load what it needs */
  "edit.started": () => void;
  /** the hello's model is shown: a run, a conflict or kept edits to say */
  "edit.after-hello": (info: EditInfo) => void;
  /** true while the folder has no model yet */
  "edit.empty": () => boolean | undefined;
  /** a model was created in the empty folder */
  "edit.model-created": () => void;
  /** the user's positions of diagram `id` */
  "layout.positions": (diagram: string) => Positions | undefined;
  /** diagram `d` as drawn: its collapsed regions each one box (features/regions) */
  "layout.collapse": (d: ModelDiagram) => ModelDiagram | undefined;
  /** a node is to be seen: the collapsed region that holds it opens (true when one did) */
  "region.show": (lane: string, node: string) => boolean | undefined;
  /** send edit operations (queued: one request at a time); true when applied. A problem with a
   * field of `form` (`data-field`) is shown at that field. */
  "edit.send": (ops: Op[], form?: HTMLElement) => Promise<boolean> | undefined;
  /** every queued edit is answered */
  "edit.settle": () => Promise<void> | undefined;
  /** take an answer of the server: its version, model and problems (`redraw`: show its model) */
  "edit.apply": (answer: EditAnswer, redraw: boolean) => void;
  /** whether there are edits the files do not have */
  "edit.dirty": (dirty: boolean) => void;
  "edit.save": () => void;
  "edit.history": (which: "undo" | "redo") => void;
  /** draw the palette again (the diagram, the model or the library changed) */
  "palette.render": () => void;
  /** draw the properties panel again (the selection or the model changed) */
  "props.render": () => void;
  /** focus the panel's first field matching `selector` (`ifEmpty`: only when nothing is in it) */
  "props.focus": (selector: string, ifEmpty?: boolean) => void;
  /** outline the selection (after a redraw too); the selected element of the shown diagram */
  "selection.highlight": () => Element | null | undefined;
  /** the selection was outlined: its element in the shown diagram (null: none there) */
  "selection.marked": (shown: Element | null) => void;
  /** delete the selection (asking first when it takes more with it than is seen) */
  "selection.delete": () => void;
  /** the next node clicked is connected from node `id` of `lane` */
  "connect.start": (lane: string, id: string) => void;
  "connect.cancel": () => void;
  /** files changed on disk while the page has unsaved edits: the user decides */
  "conflict.show": (changed: string[]) => void;
  /** show a notice in place of the one shown; false when it was not shown (notices/policy.ts) */
  "notice.show": (notice: Notice) => boolean | undefined;
  /** hide the notice (of `kind` only, when given) */
  "notice.hide": (kind?: string) => void;
}

export type Bus = EventBus<StudioEvents>;

/** A notice of the bar over the canvas: what happened, and the user's ways out. */
export interface Notice {
  /** what it is about (`data-kind`: error, hint, conflict, recovery, run, saved…) */
  kind: string;
  text: string;
  actions?: NoticeAction[];
  /** hidden after this long (0: stays until closed or replaced) */
  hideAfterMs?: number;
  /** the files it is about (`data-files`) */
  files?: string[];
}
export interface NoticeAction {
  /** `data-action` */
  action: string;
  label: string;
  title?: string;
  run: () => void | Promise<void>;
}
