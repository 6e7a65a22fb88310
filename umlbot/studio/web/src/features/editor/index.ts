// Edit mode (when the hello has `edit`): the Editor of edit.ts, wired to the bus.

import type { Studio } from "../../core/studio";
import { Editor, type EditorHost } from "../../edit";

export function install({ bus, store, hooks, canvas, frames }: Studio): void {
  let editor: Editor | null = null;
  const host: EditorHost = {
    canvas: canvas.el,
    model: () => store.model,
    current: () => canvas.current,
    scale: () => canvas.shown()?.view?.k ?? 1,
    select: (id) => bus.emit("diagram.select", id),
    setModel: (m, d) => bus.emit("model.edited", m, d),
    relayout: () => bus.emit("model.relayout"),
    diagnostics: () => store.diagnostics,
    resetLive: () => bus.emit("live.reset"),
  };

  bus.on("edit.hello", (info) => {
    if (editor) editor.setInfo(info);
    else {
      hooks.edit = {
        version: info.version,
        busy: false,
        dirty: info.dirty,
        requests: 0,
        errors: [],
        drawn: -1,
        timings: [],
      };
      editor = new Editor(host, info, hooks.edit);
    }
  });
  bus.on("edit.after-hello", (info) => editor?.afterHello(info));
  bus.on("edit.empty", () => editor?.info.empty);
  bus.on("model.missing", (message) => {
    if (editor?.info.empty) editor.showEmpty(message);
    editor?.renderPalette();
  });
  bus.on("diagram.shown", (id) => editor?.diagramShown(id));
  bus.on("layout.positions", (id) => editor?.positions(id));
  bus.on("selection.highlight", () => editor?.highlightSelection());
  bus.on("canvas.press", (ev) => editor?.pointerDown(ev));
  bus.on("key.edit", (ev) => editor?.key(ev));
  bus.on("server.files", (msg) => {
    editor?.onFiles(msg);
    frames.schedule();
  });
  bus.on("server.conflict", (msg) => editor?.onConflict(msg));
  bus.on("server.run", (msg) => editor?.onRun(msg));
  // The last edit is shown once the diagram draws its version and every node change (its
  // diagnostics among them) is drawn: the end of this frame (`window.__studio.edit.timings`).
  bus.on("frame.drawn", () => {
    const timings = hooks.edit?.timings ?? [];
    const last = timings[timings.length - 1];
    if (last && last.shown === undefined && hooks.edit!.drawn >= last.version && !store.live.dirtyNodes.size) {
      last.shown = performance.now();
    }
  });
  // The editor asks for a fresh hello (the server's working copy) after a stale edit.
  window.addEventListener("studio-resync", () => bus.emit("session.resync"));
}
