// Edit mode (when the hello has `edit`): the page never writes the model format; it sends
// operations to the studio (contract: docs/studio.md, "Editing") and draws the model it answers
// with, the studio's compiler checks every edit. This feature holds the edit session (store.edit,
// `window.__studio.edit`), sends the edits and takes the answers.

import { $ } from "../../core/dom";
import { renamedSelection, validSelection } from "../../core/selection";
import type { Studio } from "../../core/studio";
import type { EditAnswer, EditInfo, Library } from "../../model/types";
import { EditQueue } from "./queue";

export function install(studio: Studio): void {
  const { bus, store, hooks } = studio;
  const tools = $<HTMLElement>("#edit-tools");
  const palette = $<HTMLElement>("#palette");
  const props = $<HTMLElement>("#props");
  const queue = new EditQueue(studio);

  const start = (info: EditInfo): void => {
    hooks.edit = {
      version: info.version,
      busy: false,
      dirty: info.dirty,
      requests: 0,
      errors: [],
      drawn: -1,
      timings: [],
      send: (ops) => queue.send(ops),
    };
    store.edit = { info, library: null, positions: info.layout?.positions ?? {}, selection: null };
    document.body.classList.add("editing");
    tools.hidden = info.empty; // Undo, Save, Run: once there is a model
    palette.hidden = false;
    props.hidden = false;
    bus.emit("edit.dirty", info.dirty);
    void loadLibrary(studio);
    bus.emit("edit.started");
    bus.emit("props.render");
  };

  /** A new hello (reconnect): the server's state wins. */
  const again = (info: EditInfo): void => {
    const edit = store.edit!;
    edit.info = info;
    tools.hidden = info.empty;
    edit.positions = info.layout?.positions ?? {};
    hooks.edit!.version = info.version;
    bus.emit("edit.dirty", info.dirty);
    bus.emit("props.render");
    bus.emit("palette.render");
  };

  /** An answer of the server: the new version, model and problems. */
  const apply = (a: EditAnswer, redraw: boolean): void => {
    const edit = store.edit!;
    hooks.edit!.version = a.version;
    if (a.lane_files) edit.info.lane_files = a.lane_files;
    if (a.layout?.positions) edit.positions = a.layout.positions;
    bus.emit("edit.dirty", a.dirty);
    edit.selection = renamedSelection(edit.selection, a.renamed ?? []);
    if (redraw && a.model !== undefined) {
      bus.emit("model.edited", a.model, a.diagnostics ?? []);
      edit.selection = validSelection(edit.selection, store.model);
      bus.emit("palette.render");
      bus.emit("props.render");
    }
  };

  bus.on("edit.hello", (info) => (store.edit ? again(info) : start(info)));
  bus.on("edit.empty", () => store.edit?.info.empty);
  bus.on("edit.model-created", () => {
    store.edit!.info.empty = false;
    tools.hidden = false;
  });
  bus.on("layout.positions", (id) => (store.edit ? (store.edit.positions[id] ?? {}) : undefined));
  bus.on("edit.send", (ops, form) => queue.send(ops, form));
  bus.on("edit.settle", () => queue.settle());
  bus.on("edit.apply", apply);
  // The last edit is shown once the diagram draws its version and every node change (its
  // diagnostics among them) is drawn: the end of this frame (`window.__studio.edit.timings`).
  bus.on("frame.drawn", () => {
    const timings = hooks.edit?.timings ?? [];
    const last = timings[timings.length - 1];
    if (last && last.shown === undefined && hooks.edit!.drawn >= last.version && !store.live.dirtyNodes.size) {
      last.shown = performance.now();
    }
  });
}

/** The component library and node kinds (`GET /api/library`): the palette and the properties show them. */
async function loadLibrary({ bus, store }: Studio): Promise<void> {
  try {
    const res = await fetch("/api/library");
    if (!res.ok) throw new Error(`${res.status}`);
    store.edit!.library = (await res.json()) as Library;
  } catch (exc) {
    console.error("studio: no component library", exc);
  }
  bus.emit("palette.render");
  bus.emit("props.render");
}
