// A session starts with each hello (the first, and one per reconnection): every feature forgets
// the previous session, the toolbar says which model, robot and mode, the hello's model is shown.
// The robot id may change within a session (a model created or renamed): the counts start again.

import { $ } from "../../core/dom";
import type { Studio } from "../../core/studio";
import type { HelloMsg } from "../../model/types";

export function install({ bus, store, hooks, frames }: Studio): void {
  const titleEl = $<HTMLElement>("#title");
  const sourceEl = $<HTMLElement>("#source");
  const modeEl = $<HTMLElement>("#mode");

  const start = (hello: HelloMsg): void => {
    hooks.hellos += 1;
    store.mode = hello.mode === "replay" ? "replay" : "live";
    // The editor draws the model as written (it exists while the model has errors too).
    const shown = hello.edit ? (hello.edit.model ?? null) : hello.model;
    const shownDiagnostics = hello.edit
      ? (hello.edit.diagnostics ?? hello.diagnostics ?? [])
      : (hello.diagnostics ?? []);
    bus.emit("session.reset", hello, shown);
    store.robot = hello.robot;
    // an empty folder has no name yet (the robot is followed under the name it is given)
    const fresh = !!hello.edit?.empty;
    const name = shown?.name ?? (fresh ? "new model" : "(no model)");
    titleEl.textContent = fresh ? name : `${name} · robot ${hello.robot}`;
    sourceEl.textContent = hello.source;
    sourceEl.title = hello.source;
    titleEl.title = hello.source;
    const mode = store.mode;
    modeEl.textContent = mode === "replay" ? `replay${hello.replay ? ` · ${hello.replay.file}` : ""}` : "live";
    modeEl.dataset.mode = mode;
    document.title = `umlbot studio — ${name} (${mode})`;
    if (hello.edit) bus.emit("edit.hello", hello.edit);
    bus.emit("model.set", shown, shownDiagnostics, false);
    if (hello.edit) bus.emit("edit.after-hello", hello.edit);
    bus.emit("session.started", hello);
    store.live.markAllDirty();
    frames.schedule();
  };

  bus.on("server.hello", start);
  bus.on("model.shown", (m) => {
    titleEl.textContent = `${m.name} · robot ${store.robot}`;
  });
  bus.on("server.robot", (msg) => {
    // the robot id follows the model's name: what the page showed was the previous robot's
    store.robot = msg.robot;
    titleEl.textContent = `${store.model?.name ?? "(no model)"} · robot ${store.robot}`;
    bus.emit("live.reset");
  });
}
