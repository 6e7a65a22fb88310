// Edit mode: palette, properties, call/guard editor with completion, undo/redo, save, notices
// for files changed on disk, run/stop. The page never writes the model format: it sends
// operations to the server (contract: docs/studio.md, "Editing") and draws the model view it
// answers with; the server's compiler checks every edit.

import { $, el } from "./core/dom";
import type { EditHooks } from "./core/hooks";
import type { Positions } from "./draw/layout";
import { sameFile } from "./model/paths";
import type {
  CompleteAnswer,
  Completion,
  ConflictMsg,
  Diagnostic,
  EditAnswer,
  EditInfo,
  FeatureInfo,
  FilesMsg,
  ImplInfo,
  JsonSchema,
  LayoutMap,
  Library,
  ModelComponent,
  ModelEdge,
  ModelLane,
  ModelNode,
  ModelView,
  NodeKind,
  Op,
  Renamed,
  RunMsg,
} from "./model/types";
import { runEndText, speedWords } from "./runtext";

export interface EditorHost {
  canvas: HTMLElement;
  model(): ModelView | null;
  current(): string;
  scale(): number;
  select(id: string): void;
  setModel(m: ModelView | null, diagnostics: Diagnostic[]): void;
  /** Draw the model again (the user's positions changed). */
  relayout(): void;
  diagnostics(): Diagnostic[];
  /** A new run starts: forget the previous run's counts. */
  resetLive(): void;
}

type Selection =
  | { type: "node"; lane: string; id: string }
  | { type: "edge"; lane: string; source: string; target: string }
  | { type: "component"; name: string }
  | { type: "lane"; lane: string }
  | { type: "new-component"; impl: string }
  | null;

/** Field types (the server's library) that are flows: edited by connecting nodes, never as text. */
const FLOW_TYPES = new Set(["node", "nodes", "branches"]);
/** An empty guard's input: the output is unfinished (the checker reports it) until one is typed. */
const GUARD_PLACEHOLDER = "type this output's guard";

/** Notices that wait for the user's decision, and notices that only pass by (`showNotice`). */
const DECISION_NOTICES = new Set(["conflict", "recovery"]);
const PASSING_NOTICES = new Set(["run", "run-goal", "run-ended", "hint"]);

export function signatureText(name: string, f: FeatureInfo): string {
  const ret = f.returns && f.returns !== "none" ? ` → ${f.returns}` : "";
  return f.params === null ? `${name}${ret}` : `${name}(${f.params.map(paramText).join(", ")})${ret}`;
}
export function paramText(p: {
  name: string;
  type?: string;
  minimum?: number | null;
  maximum?: number | null;
  unit?: string | null;
}): string {
  let s = p.name;
  if (p.type) s += `: ${p.type}`;
  const lo = p.minimum ?? null;
  const hi = p.maximum ?? null;
  if (lo !== null && hi !== null) s += ` ${lo}..${hi}`;
  else if (lo !== null) s += ` ≥ ${lo}`;
  else if (hi !== null) s += ` ≤ ${hi}`;
  if (p.unit) s += ` ${p.unit}`;
  return s;
}

/** A typed text as the value to send: numbers and booleans as such, the rest as text. */
function typed(field: string, text: string, type: string | undefined): unknown {
  const t = text.trim();
  if (t === "") return null;
  if (field === "call" || field === "name" || field === "signal" || field === "store") return t;
  if (/^-?\d+(\.\d+)?$/.test(t) && (!type || /number|integer|float|value|any/.test(type) || field === "value"))
    return Number(t);
  if ((t === "true" || t === "false") && (!type || /bool|value|any/.test(type) || field === "value"))
    return t === "true";
  return t;
}

function resolve(s: JsonSchema, root: JsonSchema): JsonSchema {
  let cur = s;
  for (let i = 0; i < 8; i++) {
    if (cur.$ref) {
      const name = cur.$ref.split("/").pop() ?? "";
      cur = { ...(root.$defs?.[name] ?? {}), ...cur, $ref: undefined };
      continue;
    }
    if (cur.anyOf) {
      const pick = cur.anyOf.find((x) => x.type !== "null") ?? cur.anyOf[0];
      cur = { ...pick, ...cur, anyOf: undefined, type: pick.type };
      continue;
    }
    break;
  }
  return cur;
}

export class Editor {
  info: EditInfo;
  library: Library | null = null;
  hooks: EditHooks;
  private host: EditorHost;
  private layout: LayoutMap;
  private sel: Selection = null;
  private connectFrom: { lane: string; id: string } | null = null;
  private queue: { ops: Op[]; resolve: (ok: boolean) => void; form?: HTMLElement }[] = [];
  private forceSave = false;
  private laneFile = "";
  /** the next drawing of a component's properties shows its first deployment problem */
  private revealProblems = false;

  private tools = $<HTMLElement>("#edit-tools");
  private palette = $<HTMLElement>("#palette");
  private props = $<HTMLElement>("#props");
  private notice = $<HTMLElement>("#notice");
  private saveBtn = $<HTMLButtonElement>("#save");
  private undoBtn = $<HTMLButtonElement>("#undo");
  private redoBtn = $<HTMLButtonElement>("#redo");
  private runBtn = $<HTMLButtonElement>("#run");
  private stopBtn = $<HTMLButtonElement>("#stop");
  private trackSel = $<HTMLSelectElement>("#track");

  constructor(host: EditorHost, info: EditInfo, hooks: EditHooks) {
    this.host = host;
    this.info = info;
    this.hooks = hooks;
    this.layout = info.layout?.positions ?? {};
    document.body.classList.add("editing");
    this.tools.hidden = info.empty; // Undo, Save, Run: once there is a model
    this.palette.hidden = false;
    this.props.hidden = false;
    this.hooks.version = info.version;
    this.hooks.send = (ops) => this.edit(ops);
    this.setDirty(info.dirty);
    this.saveBtn.onclick = () => void this.save();
    this.undoBtn.onclick = () => void this.history("undo");
    this.redoBtn.onclick = () => void this.history("redo");
    this.runBtn.onclick = () => void this.run();
    this.stopBtn.onclick = () => void this.stop();
    void this.loadLibrary();
    void this.loadTracks();
    this.renderProps();
    // a double click on a node, a lane's title or a component: its name, ready to be typed over
    host.canvas.addEventListener("dblclick", (ev) => {
      const t = ev.target as Element;
      if (!t.closest?.("g.node, g.component, .lane-header, .lane-title, .lane-sub")) return;
      const input = this.props.querySelector<HTMLInputElement>('input[name="rename"]');
      if (!input) return;
      input.focus();
      input.select();
    });
  }

  /** A new hello (reconnect): the server's state wins. */
  setInfo(info: EditInfo): void {
    this.info = info;
    this.tools.hidden = info.empty;
    this.layout = info.layout?.positions ?? {};
    this.hooks.version = info.version;
    this.setDirty(info.dirty);
    this.renderProps();
    this.renderPalette();
  }

  /** After the hello's model is drawn: a run going on (or ended), a standing conflict, kept edits.
   * A conflict or kept edits wait for the user's decision: a run's notice never hides them. */
  afterHello(info: EditInfo): void {
    if (info.run) this.onRun({ type: "run", state: info.run.running ? "running" : "ended", ...info.run }, true);
    if (info.conflict?.length) this.showConflict(info.conflict);
    else if (info.recovery) this.showRecovery(info.recovery);
  }

  /** Edits a previous studio kept when it quit unsaved: the user restores or discards them. */
  private showRecovery(r: NonNullable<EditInfo["recovery"]>): void {
    const when = r.time ?? "a previous session";
    const what = [...r.files, ...(r.layout ? ["positions"] : [])].join(", ");
    this.showNotice(
      "recovery",
      `The studio quit with unsaved edits (${what}); they were kept, your files are unchanged. Restore them into the page, or discard them for good.`,
      [
        [
          "restore",
          `Restore the unsaved edits of ${when}`,
          async () => {
            const a = await this.request<EditAnswer>("/api/recover", { action: "restore" });
            if (a) {
              this.apply(a);
              this.showNotice(
                "restored",
                `Restored the edits of ${when}: Save writes them, Undo goes back to the files.`,
                [],
                8000,
              );
            }
          },
        ],
        [
          "discard",
          "Discard them",
          async () => {
            if (await this.request<EditAnswer>("/api/recover", { action: "discard" })) {
              this.showNotice("discarded", "The kept edits were discarded.", [], 4000);
            }
          },
        ],
      ],
    );
    this.notice
      .querySelector('[data-action="restore"]')
      ?.setAttribute("title", "Put the kept edits back into the page (not saved yet: Save writes them)");
    this.notice
      .querySelector('[data-action="discard"]')
      ?.setAttribute("title", "Delete the kept edits for good; your model files stay as they are");
  }

  /** `again`: the hello repeats a run that ended already (a reload): its end was said once. */
  onRun(msg: RunMsg, again = false): void {
    this.setRunning(msg.running ?? msg.state === "running");
    const r = msg.result;
    const key = `umlbot-studio-run-end:${this.info.token}`;
    const stamp = JSON.stringify(r ?? null);
    if (msg.state === "ended" && r && again) {
      let seen = false;
      try {
        seen = localStorage.getItem(key) === stamp;
      } catch {
        /* no storage: say it */
      }
      if (seen) return;
    }
    if (
      msg.state === "ended" &&
      r &&
      this.showNotice(r.goal_reached ? "run-goal" : "run-ended", runEndText(r), [], 10000)
    ) {
      try {
        localStorage.setItem(key, stamp); // said: a reload does not say it again
      } catch {
        /* no storage */
      }
    }
  }

  positions(diagram: string): Positions {
    return this.layout[diagram] ?? {};
  }

  /** The canvas content for a folder with no model: offer a starter model. */
  showEmpty(target: HTMLElement): void {
    target.replaceChildren();
    const form = el("form", { id: "new-model-form" }, target);
    el("h2", {}, form, "This folder has no model yet");
    el(
      "p",
      {},
      form,
      `Start one in ${this.info.root}: a starter model with the car's components, their deployment and a main activity (start → end).`,
    );
    const label = el("label", { for: "model-name", class: "field-label" }, form, "Robot name");
    const name = el(
      "input",
      {
        id: "model-name",
        name: "model-name",
        placeholder: "e.g. my_robot",
        value: this.info.root.split("/").filter(Boolean).pop() ?? "my_robot",
        required: "",
        "data-field": "name",
        "aria-describedby": "model-name-hint",
      },
      form,
    );
    el(
      "small",
      { id: "model-name-hint", class: "hint" },
      form,
      "letters, digits, _ and -; it is also the robot's id on the broker",
    );
    label.title = "the model's name";
    const btn = el("button", { id: "new-model", type: "submit" }, form, "Create the model");
    form.onsubmit = async (ev) => {
      ev.preventDefault();
      btn.disabled = true;
      clearFieldErrors(form);
      const a = await this.request<EditAnswer>("/api/new", { name: name.value.trim() }, false, form);
      btn.disabled = false;
      if (a) {
        this.info.empty = false;
        this.tools.hidden = false;
        this.apply(a);
      }
    };
  }

  // ------------------------------------------------------------------ server

  /** POST to the studio with the token; null (and a notice, unless `quiet`) when it failed. */
  private async request<T>(
    path: string,
    body: Record<string, unknown>,
    quiet = false,
    form?: HTMLElement,
  ): Promise<T | null> {
    this.hooks.requests += 1;
    try {
      const res = await fetch(path, {
        method: "POST",
        headers: { "Content-Type": "application/json" },
        body: JSON.stringify({ token: this.info.token, ...body }),
      });
      const text = await res.text();
      let data: unknown = null;
      try {
        data = text ? JSON.parse(text) : null;
      } catch {
        data = { error: text };
      }
      if (res.status === 409 && /^\/api\/(undo|redo)$/.test(path)) {
        this.showNotice("hint", (data as { error?: string } | null)?.error ?? `nothing to ${path.slice(5)}`, [], 3000);
        return null;
      }
      if (!res.ok) {
        const failed = data as { error?: string; message?: string; fields?: Record<string, string> } | null;
        const err = failed?.message ?? failed?.error ?? `${res.status} ${res.statusText}`;
        if (quiet) return null;
        if (form && failed?.fields && markFieldErrors(form, failed.fields)) {
          // said at the field(s) it is about; a notice of an earlier problem is stale now
          this.clearErrorNotice();
        } else if (res.status === 409 && (data as { conflict?: string[] } | null)?.conflict) {
          this.showConflict((data as { conflict: string[] }).conflict);
        } else if (res.status === 409 && path === "/api/edit") {
          // another window edited meanwhile: take the server's state (a fresh hello) and say so
          this.showNotice("error", `${err} — the page takes the server's current model.`, [], 8000);
          this.resync();
        } else this.showNotice("error", err, []);
        this.hooks.errors.push(err);
        return null;
      }
      if (!quiet) this.clearErrorNotice(); // it worked: an error shown before is over
      return data as T;
    } catch (exc) {
      if (quiet) return null;
      this.showNotice("error", `The studio server did not answer: ${String(exc)}`, []);
      return null;
    }
  }

  /** An error notice goes when a later request succeeds (what it said is fixed or moot). */
  private clearErrorNotice(): void {
    if (this.notice.dataset.kind === "error") this.notice.hidden = true;
  }

  /** Apply operations (queued: one request at a time, each with the version it edits); a problem
   * with a field of `form` (`data-field`) is shown at that field. */
  edit(ops: Op[], form?: HTMLElement): Promise<boolean> {
    if (form) clearFieldErrors(form);
    return new Promise((resolve) => {
      this.queue.push({ ops, resolve, form });
      if (this.queue.length === 1) void this.pump();
    });
  }

  private async pump(): Promise<void> {
    this.hooks.busy = true;
    while (this.queue.length) {
      const { ops, resolve, form } = this.queue[0];
      const sent = performance.now();
      const a = await this.request<EditAnswer>("/api/edit", { version: this.hooks.version, ops }, false, form);
      if (a) {
        const timings = this.hooks.timings;
        timings.push({ version: a.version, sent, answered: performance.now() });
        if (timings.length > 200) timings.shift();
        this.apply(a, !ops.every((o) => o.op === "set_layout"));
      }
      this.queue.shift();
      resolve(!!a);
    }
    this.hooks.busy = false;
  }

  /** An answer of the server: the new version, model and problems. */
  apply(a: EditAnswer, redraw = true): void {
    this.hooks.version = a.version;
    if (a.lane_files) this.info.lane_files = a.lane_files;
    if (a.layout?.positions) this.layout = a.layout.positions;
    this.setDirty(a.dirty);
    this.followRenames(a.renamed ?? []);
    if (redraw && a.model !== undefined) {
      this.host.setModel(a.model, a.diagnostics ?? []);
      this.validateSelection();
      this.renderPalette();
      this.renderProps();
    }
  }

  /** What an edit, undo or redo renamed: the selection keeps the renamed thing (a rename's undo
   * selects the node under its old id again, so the panel shows that id, not a stale one). */
  private followRenames(renamed: Renamed[]): void {
    for (const r of renamed) {
      const s = this.sel;
      if (!s) return;
      if (r.kind === "node") {
        if (s.type === "node" && s.lane === r.lane && s.id === r.old) this.sel = { ...s, id: r.new };
        else if (s.type === "edge" && s.lane === r.lane) {
          this.sel = {
            ...s,
            source: s.source === r.old ? r.new : s.source,
            target: s.target === r.old ? r.new : s.target,
          };
        }
      } else if (
        r.kind === "lane" &&
        (s.type === "node" || s.type === "edge" || s.type === "lane") &&
        s.lane === r.old
      ) {
        this.sel = { ...s, lane: r.new };
      } else if (r.kind === "component") {
        if (s.type === "component" && s.name === r.old) this.sel = { ...s, name: r.new };
        else if ((s.type === "node" || s.type === "edge" || s.type === "lane") && s.lane === r.old)
          this.sel = { ...s, lane: r.new };
      }
    }
  }

  /** Reconnect: the server's hello carries its working copy, version and layout. */
  private resync(): void {
    window.dispatchEvent(new Event("studio-resync"));
  }

  private setDirty(dirty: boolean): void {
    this.hooks.dirty = dirty;
    this.saveBtn.dataset.dirty = String(dirty);
    this.saveBtn.textContent = dirty ? "Save •" : "Saved";
    this.saveBtn.title = dirty ? "Write the edits to the model files (Ctrl-S)" : "Nothing to save";
    document.title = document.title.replace(/^• /, "");
    if (dirty) document.title = `• ${document.title}`;
  }

  async save(): Promise<void> {
    await this.settle();
    const a = await this.request<{ saved: string[]; dirty: boolean; version?: number }>("/api/save", {
      version: this.hooks.version,
      force: this.forceSave,
    });
    if (!a) return;
    this.forceSave = false;
    if (a.version !== undefined) this.hooks.version = a.version;
    this.setDirty(a.dirty);
    this.showNotice(
      "saved",
      a.saved.length ? `Saved ${a.saved.join(", ")}` : "Nothing changed: no file written",
      [],
      3000,
    );
  }

  /** Wait until every queued edit is answered. */
  private async settle(): Promise<void> {
    if (!this.queue.length) return;
    await new Promise<void>((resolve) => {
      this.queue.push({ ops: [], resolve: () => resolve() });
    });
  }

  async history(which: "undo" | "redo"): Promise<void> {
    await this.settle();
    this.hooks.busy = true;
    const a = await this.request<EditAnswer>(`/api/${which}`, {});
    if (a) this.apply(a);
    this.hooks.busy = false;
  }

  /** A file changed on disk while the page was clean: the server reloaded it. */
  onFiles(msg: FilesMsg): void {
    this.hooks.version = msg.version;
    if (msg.lane_files) this.info.lane_files = msg.lane_files;
    if (msg.layout?.positions) this.layout = msg.layout.positions;
    this.setDirty(msg.dirty ?? false);
    this.host.setModel(msg.model, msg.diagnostics ?? []);
    this.validateSelection();
    this.renderPalette();
    this.renderProps();
    this.showNotice(
      "reloaded",
      `${msg.changed.join(", ")} ${msg.changed.length === 1 ? "was" : "were"} changed on disk: reloaded.`,
      [],
      8000,
    );
  }

  /** A file changed on disk while the page has unsaved edits: the user decides. */
  onConflict(msg: ConflictMsg): void {
    if (msg.version !== undefined) this.hooks.version = msg.version;
    this.showConflict(msg.changed);
  }

  private showConflict(changed: string[]): void {
    this.showNotice(
      "conflict",
      `${changed.join(", ")} changed on disk while you have unsaved edits. Nothing was overwritten.`,
      [
        [
          "reload",
          "Reload from disk (discard my edits)",
          async () => {
            const a = await this.request<EditAnswer>("/api/reload", {});
            if (a) {
              this.forceSave = false;
              this.apply(a);
              this.showNotice("reloaded", "Reloaded from disk: your unsaved edits were discarded.", [], 6000);
            }
          },
        ],
        [
          "keep",
          "Keep mine",
          () => {
            this.forceSave = true;
            this.showNotice("kept", `Your edits are kept; Save will replace ${changed.join(", ")} on disk.`, [], 8000);
          },
        ],
      ],
    );
    this.notice.dataset.files = changed.join(" ");
  }

  /** Show a notice in place of the one shown; false when it was not shown: a passing notice (a
   * run's, a hint) never replaces a notice that waits for the user's decision (a conflict with the
   * disk, unsaved edits kept at quit) — the decision's buttons are the way out of that. */
  showNotice(
    kind: string,
    text: string,
    actions: [string, string, () => void | Promise<void>][],
    hideAfterMs = 0,
  ): boolean {
    const n = this.notice;
    if (PASSING_NOTICES.has(kind) && !n.hidden && DECISION_NOTICES.has(n.dataset.kind ?? "")) return false;
    n.replaceChildren();
    n.dataset.kind = kind;
    delete n.dataset.files;
    el("span", { class: "text" }, n, text);
    for (const [action, label, fn] of actions) {
      const b = el("button", { type: "button", "data-action": action }, n, label);
      b.onclick = () => void fn();
    }
    // what closing does, in words: it hides the notice; it never undoes, discards or saves anything
    const later = kind === "recovery";
    const close = el("button", { type: "button", "data-action": "dismiss" }, n, later ? "Decide later" : "×");
    close.title = later
      ? "Hide this notice: the kept edits stay in the recovery file, unrestored and not discarded; the next start of the studio offers them again"
      : "Hide this notice (nothing is undone)";
    close.setAttribute("aria-label", later ? "Decide later" : "Hide this notice");
    close.onclick = () => {
      n.hidden = true;
    };
    n.hidden = false;
    if (hideAfterMs) {
      const stamp = String(performance.now());
      n.dataset.stamp = stamp;
      setTimeout(() => {
        if (n.dataset.stamp === stamp) n.hidden = true;
      }, hideAfterMs);
    } else delete n.dataset.stamp;
    return true;
  }

  // ------------------------------------------------------------------ library, tracks, run

  private async loadLibrary(): Promise<void> {
    try {
      const res = await fetch("/api/library");
      if (!res.ok) throw new Error(`${res.status}`);
      this.library = (await res.json()) as Library;
    } catch (exc) {
      console.error("studio: no component library", exc);
    }
    this.renderPalette();
    this.renderProps();
  }

  private async loadTracks(): Promise<void> {
    try {
      const res = await fetch("/api/tracks");
      const data = (await res.json()) as { tracks: ({ name: string; title?: string } | string)[] };
      this.trackSel.replaceChildren();
      for (const t of data.tracks ?? []) {
        const name = typeof t === "string" ? t : t.name;
        el("option", { value: name }, this.trackSel, typeof t === "string" ? t : (t.title ?? t.name));
      }
    } catch (exc) {
      console.error("studio: no tracks", exc);
    }
  }

  private async run(): Promise<void> {
    await this.settle();
    const speed = Number($<HTMLSelectElement>("#run-speed").value) || 2;
    const a = await this.request<{ running?: boolean; error?: string }>("/api/run", {
      track: this.trackSel.value,
      speed,
    });
    if (!a) return;
    this.setRunning(true);
    this.host.resetLive();
    this.showNotice(
      "run",
      `Running the edited model in the simulator on ${this.trackSel.value} at ${speed}× (${speedWords(speed)}).`,
      [],
      4000,
    );
  }

  private async stop(): Promise<void> {
    await this.request("/api/stop", {});
    this.setRunning(false);
  }

  setRunning(running: boolean): void {
    this.runBtn.dataset.running = String(running);
    this.stopBtn.disabled = !running;
  }

  // ------------------------------------------------------------------ palette

  diagramShown(_id: string): void {
    if (this.sel?.type === "new-component" && this.host.current() !== "components") this.sel = null;
    this.renderPalette();
    this.renderProps();
  }

  renderPalette(): void {
    const p = this.palette;
    p.replaceChildren();
    const m = this.host.model();
    const cur = this.host.current();
    if (cur === "components" || !m) {
      el("div", { class: "panel-title" }, p, "Component library");
      if (this.info.empty) {
        // browsable before there is a model; adding a part needs the model it goes into
        el(
          "div",
          { class: "hint", "data-hint": "no-model" },
          p,
          "There is no model yet: create it first (the form in the middle). Then click a part here to add it to the model.",
        );
      }
      if (!this.library) {
        el("div", { class: "hint" }, p, "loading…");
        return;
      }
      const byKind = new Map<string, ImplInfo[]>();
      for (const impl of this.library.implementations) {
        const list = byKind.get(impl.kind) ?? [];
        list.push(impl);
        byKind.set(impl.kind, list);
      }
      for (const [kind, impls] of byKind) {
        const group = el("div", { class: "group", "data-group": kind }, p);
        el("div", { class: "group-title" }, group, kind);
        for (const impl of impls) {
          const item = el(
            "div",
            { class: "item impl", "data-impl": impl.id, "data-kind": impl.kind, tabindex: "0" },
            group,
          );
          el("b", {}, item, impl.id);
          if (impl.service) el("small", {}, item, ` · ${impl.service}`);
          const feats = features(impl, this.library);
          const list = el("div", { class: "features" }, item);
          for (const [f, info] of Object.entries(feats))
            el("div", { "data-feature": f }, list, info ? signatureText(f, info) : f);
          if (impl.aliases.length) el("div", { class: "aliases" }, item, `seeds: ${impl.aliases.join(", ")}`);
          item.title = impl.title ?? impl.doc ?? `${impl.kind} ${impl.id}`;
          item.onclick = () => {
            this.sel = { type: "new-component", impl: impl.id };
            this.renderProps();
            this.props.querySelector<HTMLInputElement>('[name="name"]')?.focus();
          };
        }
      }
      return;
    }
    el("div", { class: "panel-title" }, p, "Nodes");
    el("div", { class: "hint" }, p, "drag onto a swimlane, or click to add to the selected one");
    const grid = el("div", { class: "kinds" }, p);
    // the node kinds are the compiler's (the server's library), in its order
    if (!this.library) el("div", { class: "hint" }, grid, "loading…");
    for (const [kind, info] of Object.entries(this.library?.node_kinds ?? {})) {
      const item = el(
        "div",
        { class: `item node-kind kind-${kind}`, "data-kind": kind, tabindex: "0", title: info.doc ?? kind },
        grid,
      );
      el("i", { class: "icon" }, item);
      el("span", {}, item, kind);
      item.addEventListener("pointerdown", (ev) => this.dragKind(ev, kind));
    }
    el("div", { class: "panel-title" }, p, "Swimlanes");
    const form = el("form", { class: "add-lane" }, p);
    const lane = el(
      "input",
      {
        name: "lane-name",
        placeholder: "component or new activity",
        list: "lane-options",
        autocomplete: "off",
        "data-field": "lane",
      },
      form,
    );
    const dl = el("datalist", { id: "lane-options" }, form);
    const used = new Set(m.diagrams.flatMap((d) => d.lanes.map((l) => l.name)));
    for (const c of m.components) if (!used.has(c.name)) el("option", { value: c.name }, dl);
    const file = el("select", { name: "lane-file", title: "where the lane is written" }, form);
    el("option", { value: "" }, file, "in a new file");
    // only the files a lane can be added to (the server says which: a `lanes:` list)
    for (const f of this.info.lane_files ?? []) el("option", { value: f }, file, `in ${f}`);
    file.value = this.info.lane_files?.includes(this.laneFile) ? this.laneFile : "";
    file.onchange = () => {
      this.laneFile = file.value;
    };
    el("button", { type: "submit", "data-action": "add-lane" }, form, "Add swimlane");
    el(
      "div",
      { class: "hint" },
      form,
      "a component's name runs on it; any other name is a virtual lane (a called activity)",
    );
    form.onsubmit = async (ev) => {
      ev.preventDefault();
      const name = lane.value.trim();
      if (!name) return;
      const op: Op = { op: "add_lane", lane: name };
      if (file.value) op.file = file.value;
      if (await this.edit([op], form)) {
        lane.value = "";
        const d = this.host.model()?.diagrams.find((x) => x.lanes.some((l) => l.name === name));
        if (d) this.host.select(d.id);
        this.sel = { type: "lane", lane: name };
        this.renderProps();
      }
    };
  }

  /** Drag a node kind from the palette onto a lane (a click adds it to the selected lane). */
  private dragKind(ev: PointerEvent, kind: NodeKind): void {
    if (ev.button !== 0) return;
    ev.preventDefault();
    const ghost = el("div", { class: "drag-ghost", "data-kind": kind }, document.body, kind);
    let moved = false;
    const sx = ev.clientX;
    const sy = ev.clientY;
    const move = (e: PointerEvent): void => {
      if (Math.hypot(e.clientX - sx, e.clientY - sy) > 4) moved = true;
      ghost.style.left = `${e.clientX + 6}px`;
      ghost.style.top = `${e.clientY + 6}px`;
      ghost.hidden = !moved;
      const lane = this.laneAt(e.clientX, e.clientY);
      for (const g of this.host.canvas.querySelectorAll("g.lane.drop")) g.classList.remove("drop");
      if (lane) this.laneG(lane)?.classList.add("drop");
    };
    const up = (e: PointerEvent): void => {
      window.removeEventListener("pointermove", move);
      window.removeEventListener("pointerup", up);
      ghost.remove();
      for (const g of this.host.canvas.querySelectorAll("g.lane.drop")) g.classList.remove("drop");
      const lane = moved ? this.laneAt(e.clientX, e.clientY) : this.selectedLane();
      if (!lane) {
        if (!moved)
          this.showNotice(
            "hint",
            "Select a swimlane first (click its header or one of its nodes), or drag the node onto it.",
            [],
            4000,
          );
        return;
      }
      void this.addNode(lane, kind);
    };
    window.addEventListener("pointermove", move);
    window.addEventListener("pointerup", up);
  }

  private laneG(lane: string): SVGGElement | null {
    return this.host.canvas.querySelector<SVGGElement>(
      `svg[data-diagram="${CSS.escape(this.host.current())}"] g.lane[data-lane="${CSS.escape(lane)}"]`,
    );
  }

  private laneAt(x: number, y: number): string | null {
    const hit = document.elementFromPoint(x, y);
    const g = hit?.closest?.("g.lane");
    return g ? g.getAttribute("data-lane") : null;
  }

  private selectedLane(): string | null {
    const s = this.sel;
    if (s && (s.type === "node" || s.type === "lane" || s.type === "edge")) return s.lane;
    const d = this.host.model()?.diagrams.find((x) => x.id === this.host.current());
    return d && d.lanes.length === 1 ? d.lanes[0].name : null;
  }

  private lane(name: string): ModelLane | undefined {
    for (const d of this.host.model()?.diagrams ?? []) for (const l of d.lanes) if (l.name === name) return l;
    return undefined;
  }

  private async addNode(lane: string, kind: NodeKind): Promise<void> {
    const l = this.lane(lane);
    const ids = new Set(l?.nodes.map((n) => n.id) ?? []);
    let n = 1;
    while (ids.has(`${kind}${n}`)) n += 1;
    const id = `${kind}${n}`;
    const node: Record<string, unknown> = { id, kind };
    if (await this.edit([{ op: "add_node", lane, node }])) {
      this.sel = { type: "node", lane, id };
      this.renderProps();
      this.highlightSelection();
      this.props.querySelector<HTMLInputElement>("input.code, input[name]")?.focus();
    }
  }

  // ------------------------------------------------------------------ canvas interaction

  /** A pointer press on the canvas in edit mode; true when the editor took it (no panning). */
  pointerDown(ev: PointerEvent): boolean {
    if (ev.button !== 0) return false;
    const target = ev.target as Element;
    const nodeG = target.closest?.("g.node");
    const compG = target.closest?.("g.component");
    const edgeG = target.closest?.("g.edge");
    const header = target.closest?.(".lane-header, .lane-title, .lane-sub");
    if (nodeG) {
      const lane = nodeG.getAttribute("data-lane")!;
      const id = nodeG.getAttribute("data-node")!;
      if (this.connectFrom) {
        const from = this.connectFrom;
        this.connectFrom = null;
        this.host.canvas.classList.remove("connecting");
        if (this.notice.dataset.kind === "hint") this.notice.hidden = true;
        if (from.lane !== lane) {
          this.showNotice("error", "A flow stays inside its swimlane: connect nodes of the same lane.", [], 5000);
          return true;
        }
        void this.connect(lane, from.id, id);
        return true;
      }
      this.dragNode(ev, nodeG as SVGGElement, lane, id);
      return true;
    }
    if (compG) {
      this.dragComponent(ev, compG as SVGGElement);
      return true;
    }
    if (edgeG && target.classList.contains("hit")) {
      this.sel = {
        type: "edge",
        lane: edgeG.getAttribute("data-lane")!,
        source: edgeG.getAttribute("data-source")!,
        target: edgeG.getAttribute("data-target")!,
      };
      this.renderProps();
      this.highlightSelection();
      return true;
    }
    if (header) {
      const lane = header.closest("g.lane")?.getAttribute("data-lane");
      if (lane) {
        this.sel = { type: "lane", lane };
        this.renderProps();
        this.highlightSelection();
        return true;
      }
    }
    if (this.connectFrom) {
      this.connectFrom = null;
      this.host.canvas.classList.remove("connecting");
    }
    return false;
  }

  /** Click selects a node; dragging it moves it (its position is kept in the layout file). */
  private dragNode(ev: PointerEvent, g: SVGGElement, lane: string, id: string): void {
    const sx = ev.clientX;
    const sy = ev.clientY;
    let moved = false;
    const k = this.host.scale();
    const move = (e: PointerEvent): void => {
      const dx = (e.clientX - sx) / k;
      const dy = (e.clientY - sy) / k;
      if (!moved && Math.hypot(e.clientX - sx, e.clientY - sy) > 4) moved = true;
      if (moved) g.setAttribute("transform", `translate(${dx},${dy})`);
    };
    const up = (e: PointerEvent): void => {
      window.removeEventListener("pointermove", move);
      window.removeEventListener("pointerup", up);
      if (!moved) {
        const rake = (e.target as Element).closest?.(".rake");
        const called = g.getAttribute("data-calls");
        if (rake && called) {
          const d = this.host.model()?.diagrams.find((x) => x.lanes.some((l) => l.name === called));
          if (d) this.host.select(d.id);
          return;
        }
        this.sel = { type: "node", lane, id };
        this.renderProps();
        this.highlightSelection();
        return;
      }
      const x = Number(g.getAttribute("data-x")) + (e.clientX - sx) / k;
      const y = Number(g.getAttribute("data-y")) + (e.clientY - sy) / k;
      const diagram = this.host.current();
      const pos = { ...(this.layout[diagram] ?? {}) };
      pos[`${lane}/${id}`] = [Math.round(Math.max(0, x)), Math.round(Math.max(0, y))];
      this.layout = { ...this.layout, [diagram]: pos };
      this.sel = { type: "node", lane, id };
      this.host.relayout();
      void this.edit([{ op: "set_layout", diagram, positions: pos }]);
    };
    window.addEventListener("pointermove", move);
    window.addEventListener("pointerup", up);
  }

  private dragComponent(ev: PointerEvent, g: SVGGElement): void {
    const name = g.getAttribute("data-component")!;
    const sx = ev.clientX;
    const sy = ev.clientY;
    let moved = false;
    const k = this.host.scale();
    const move = (e: PointerEvent): void => {
      if (!moved && Math.hypot(e.clientX - sx, e.clientY - sy) > 4) moved = true;
      if (moved) g.setAttribute("transform", `translate(${(e.clientX - sx) / k},${(e.clientY - sy) / k})`);
    };
    const up = (e: PointerEvent): void => {
      window.removeEventListener("pointermove", move);
      window.removeEventListener("pointerup", up);
      this.sel = { type: "component", name };
      if (!moved) {
        this.renderProps();
        this.highlightSelection();
        return;
      }
      const x = Number(g.getAttribute("data-x")) + (e.clientX - sx) / k;
      const y = Number(g.getAttribute("data-y")) + (e.clientY - sy) / k;
      const pos = { ...(this.layout.components ?? {}) };
      pos[name] = [Math.round(Math.max(0, x)), Math.round(Math.max(0, y))];
      this.layout = { ...this.layout, components: pos };
      this.host.relayout();
      void this.edit([{ op: "set_layout", diagram: "components", positions: pos }]);
      this.renderProps();
    };
    window.addEventListener("pointermove", move);
    window.addEventListener("pointerup", up);
  }

  /** Outline the selected node/edge/component/lane (after every redraw too); the selected element. */
  highlightSelection(): Element | null {
    for (const e of this.host.canvas.querySelectorAll(".selected")) e.classList.remove("selected");
    const s = this.sel;
    if (!s) return null;
    let q = "";
    if (s.type === "node") q = `g.node[data-lane="${CSS.escape(s.lane)}"][data-node="${CSS.escape(s.id)}"]`;
    else if (s.type === "edge")
      q = `g.edge[data-lane="${CSS.escape(s.lane)}"][data-source="${CSS.escape(s.source)}"][data-target="${CSS.escape(s.target)}"]`;
    else if (s.type === "component") q = `g.component[data-component="${CSS.escape(s.name)}"]`;
    else if (s.type === "lane") q = `g.lane[data-lane="${CSS.escape(s.lane)}"]`;
    let shown: Element | null = null;
    if (q) {
      for (const e of this.host.canvas.querySelectorAll(q)) {
        e.classList.add("selected");
        if (e.closest("svg")?.getAttribute("data-diagram") === this.host.current()) shown = e;
      }
    }
    return s.type === "lane" ? null : shown;
  }

  private validateSelection(): void {
    const s = this.sel;
    const m = this.host.model();
    if (!s || !m) return;
    if (s.type === "node" || s.type === "edge" || s.type === "lane") {
      const l = this.lane(s.lane);
      if (!l) this.sel = null;
      else if (s.type === "node" && !l.nodes.some((n) => n.id === s.id)) this.sel = null;
      else if (s.type === "edge" && !l.edges.some((e) => e.source === s.source && e.target === s.target))
        this.sel = null;
    } else if (s.type === "component" && !m.components.some((c) => c.name === s.name)) this.sel = null;
  }

  private async connect(lane: string, source: string, target: string): Promise<void> {
    // a decision's first output is its else; the server writes any other with an empty guard,
    // which the checker reports on the decision until it is typed here
    const op: Op = { op: "connect", lane, source, target };
    const src = this.lane(lane)?.nodes.find((n) => n.id === source);
    if (await this.edit([op])) {
      this.sel = src?.kind === "decision" ? { type: "edge", lane, source, target } : { type: "node", lane, id: source };
      this.renderProps();
      this.highlightSelection();
      const guard = this.props.querySelector<HTMLInputElement>('[name="guard"]');
      if (src?.kind === "decision" && guard && guard.value === "") guard.focus();
    }
  }

  /** Keys of the editor; true when handled. */
  key(ev: KeyboardEvent): boolean {
    if (this.info.empty) return false; // no model yet: nothing to save, undo or delete
    const t = ev.target as HTMLElement;
    const typing = /^(INPUT|SELECT|TEXTAREA)$/.test(t.tagName);
    const mod = ev.ctrlKey || ev.metaKey;
    const k = ev.key.toLowerCase();
    if (mod && k === "s") {
      ev.preventDefault();
      if (typing) t.blur();
      void this.save();
      return true;
    }
    // Undo/redo in a field: the field's own text undo while something is typed in it; with
    // nothing typed (e.g. the name field a new node focuses), the model's undo/redo.
    if (typing && !(mod && (k === "z" || k === "y") && t instanceof HTMLInputElement && t.value === t.defaultValue))
      return false;
    if (mod && k === "z") {
      ev.preventDefault();
      void this.history(ev.shiftKey ? "redo" : "undo");
      return true;
    }
    if (mod && k === "y") {
      ev.preventDefault();
      void this.history("redo");
      return true;
    }
    if (ev.key === "Escape") {
      this.connectFrom = null;
      this.host.canvas.classList.remove("connecting");
      return true;
    }
    if ((ev.key === "Delete" || ev.key === "Backspace") && this.sel) {
      ev.preventDefault();
      void this.removeSelection();
      return true;
    }
    return false;
  }

  /** What deleting the selection takes with it that the user may not see (null: nothing much). */
  private loss(s: NonNullable<Selection>): string | null {
    const m = this.host.model();
    if (!m) return null;
    const plural = (n: number, what: string): string => `${n} ${what}${n === 1 ? "" : "s"}`;
    if (s.type === "lane") {
      const lane = this.lane(s.lane);
      if (!lane) return null;
      const n = lane.nodes.filter((x) => x.kind !== "start" && x.kind !== "end").length;
      const alone = m.diagrams.find((d) => d.file === lane.file)?.lanes.length === 1;
      if (!n) return null;
      return `Delete the swimlane ${s.lane} with its ${plural(lane.nodes.length, "node")}${alone ? ` and its file ${lane.file}` : ""}?`;
    }
    if (s.type === "component") {
      const lanes = m.diagrams.flatMap((d) => d.lanes).filter((l) => (l.component ?? l.name) === s.name && !l.virtual);
      let calls = 0;
      for (const d of m.diagrams)
        for (const l of d.lanes)
          for (const x of l.nodes) {
            const text = [
              x.label,
              ...Object.values(x.fields ?? {}).map((v) => (typeof v === "string" ? v : JSON.stringify(v))),
            ].join(" ");
            if (new RegExp(`(^|[^\\w.])${s.name}\\.`).test(text)) calls += 1;
          }
      if (!lanes.length && !calls) return null;
      const parts = [
        lanes.length ? `${plural(lanes.length, "swimlane")} run${lanes.length === 1 ? "s" : ""} on it` : "",
        calls ? `${plural(calls, "node")} call${calls === 1 ? "s" : ""} it` : "",
      ].filter(Boolean);
      return `Delete the component ${s.name}? ${parts.join(" and ")} (${lanes.length && calls ? "they" : lanes.length ? "it" : "they"} will no longer check).`;
    }
    return null;
  }

  private async removeSelection(confirmed = false): Promise<void> {
    const s = this.sel;
    if (!s) return;
    const loss = confirmed ? null : this.loss(s);
    if (loss) {
      const what = JSON.stringify(s);
      this.showNotice("confirm", loss, [
        [
          "confirm",
          "Delete",
          async () => {
            this.notice.hidden = true;
            if (JSON.stringify(this.sel) === what) await this.removeSelection(true);
          },
        ],
        [
          "cancel",
          "Keep it",
          () => {
            this.notice.hidden = true;
          },
        ],
      ]);
      return;
    }
    let op: Op | null = null;
    if (s.type === "node") op = { op: "remove_node", lane: s.lane, id: s.id };
    else if (s.type === "edge") op = { op: "disconnect", lane: s.lane, source: s.source, target: s.target };
    else if (s.type === "component") op = { op: "remove_component", name: s.name };
    else if (s.type === "lane") op = { op: "remove_lane", lane: s.lane };
    if (op && (await this.edit([op]))) {
      this.sel = null;
      this.renderProps();
    }
  }

  // ------------------------------------------------------------------ properties

  renderProps(): void {
    const p = this.props;
    // An answer redraws the panel: the focused field keeps its focus and caret, and the text typed
    // in it that is not sent yet; a field with nothing typed shows the model's value (after an undo
    // or a rename, the value now, not the one it showed before).
    const a = document.activeElement;
    const typing =
      a instanceof HTMLInputElement && p.contains(a) && a.name
        ? {
            sel: `[name="${CSS.escape(a.name)}"]${a.dataset.target ? `[data-target="${CSS.escape(a.dataset.target)}"]` : ""}`,
            value: a.value,
            typed: a.value !== a.defaultValue,
            start: a.selectionStart,
            end: a.selectionEnd,
            what: JSON.stringify(this.sel),
          }
        : null;
    p.replaceChildren();
    if (typing)
      queueMicrotask(() => {
        const again = p.querySelector<HTMLInputElement>(typing.sel);
        if (!again || typing.what !== JSON.stringify(this.sel)) return;
        if (typing.typed && again.value !== typing.value) again.value = typing.value;
        again.focus();
        if (typing.start !== null && typing.end !== null) again.setSelectionRange(typing.start, typing.end);
      });
    el("div", { class: "panel-title" }, p, "Properties");
    const body = el("div", { class: "props-body" }, p);
    const s = this.sel;
    this.highlightSelection();
    p.dataset.selection = s ? s.type : "";
    if (!s && this.info.empty) {
      el(
        "div",
        { class: "hint", "data-hint": "no-model" },
        body,
        "There is no model yet: create it with the form in the middle. Then select a node, a flow or a component to edit it here.",
      );
      return;
    }
    if (!s) {
      el(
        "div",
        { class: "hint" },
        body,
        this.host.current() === "components"
          ? "Click a component to edit its deployment, ports and links, or pick one from the library to add it."
          : "Click a node, a flow or a swimlane header to edit it; drag nodes from the palette.",
      );
      return;
    }
    if (s.type === "node") this.nodeProps(body, s.lane, s.id);
    else if (s.type === "edge") this.edgeProps(body, s.lane, s.source, s.target);
    else if (s.type === "lane") this.laneProps(body, s.lane);
    else if (s.type === "component") this.componentProps(body, s.name);
    else if (s.type === "new-component") this.newComponentProps(body, s.impl);
  }

  private row(parent: HTMLElement, label: string): HTMLElement {
    const r = el("label", { class: "row" }, parent);
    el("span", { class: "key" }, r, label);
    return r;
  }

  private button(parent: HTMLElement, name: string, text: string, fn: () => void, cls = ""): HTMLButtonElement {
    const b = el("button", { type: "button", name, class: cls }, parent, text);
    b.onclick = fn;
    return b;
  }

  /** A name and a Rename button: the server renames it and every reference to it; a refused name
   * is said at the field. */
  private renameForm(
    body: HTMLElement,
    label: string,
    current: string,
    field: string,
    op: (name: string) => Op,
    selection: (name: string) => NonNullable<Selection>,
  ): void {
    const form = el("form", { class: "row rename", novalidate: "" }, body);
    el("span", { class: "key" }, form, label);
    const input = el(
      "input",
      {
        name: "rename",
        value: current,
        autocomplete: "off",
        spellcheck: "false",
        size: "14",
        "data-field": field,
        "data-label": label,
      },
      form,
    );
    input.title = "a new name: every reference to it in the model is renamed too";
    el("button", { type: "submit", name: "apply-rename" }, form, "Rename");
    form.onsubmit = async (ev) => {
      ev.preventDefault();
      const name = input.value.trim();
      if (!name || name === current) return;
      if (await this.edit([op(name)], form)) {
        this.sel = selection(name);
        this.renderProps();
        this.highlightSelection();
      }
    };
  }

  private nodeProps(body: HTMLElement, laneName: string, id: string): void {
    const lane = this.lane(laneName);
    const node = lane?.nodes.find((n) => n.id === id);
    if (!lane || !node) return;
    el("div", { class: "props-head" }, body, `${node.kind} · ${id}`);
    el("div", { class: "props-sub" }, body, `swimlane ${laneName} · ${lane.file}:${node.line}`);
    this.renameForm(
      body,
      "id",
      id,
      "new_id",
      (v) => ({ op: "rename_node", lane: laneName, id, new_id: v }),
      (v) => ({ type: "node", lane: laneName, id: v }),
    );
    const marks = this.host
      .diagnostics()
      .filter((d) => sameFile(d.file, lane.file) && d.line >= node.line && d.line < nextLine(lane, node));
    for (const d of marks) el("div", { class: `problem ${d.severity}`, "data-severity": d.severity }, body, d.text);
    // the kind's fields as the compiler defines them (the server's library)
    if (!this.library) el("div", { class: "hint" }, body, "loading…");
    const fields = this.library?.node_kinds[node.kind]?.fields ?? {};
    for (const [field, info] of Object.entries(fields)) {
      if (info.type && FLOW_TYPES.has(info.type)) continue;
      const r = this.row(body, field + (info.required ? " *" : ""));
      const current = fieldText(node, field);
      if (info.type === "expression") {
        // a call or an expression: edited with completion
        this.codeInput(r, field, current, laneName, (text) => {
          void this.edit([{ op: "set_node", lane: laneName, id, fields: { [field]: typed(field, text, info.type) } }]);
        });
      } else {
        const input = el("input", { name: field, value: current, autocomplete: "off", spellcheck: "false" }, r);
        if (info.doc) input.title = info.doc;
        input.onchange = () => {
          void this.edit([
            { op: "set_node", lane: laneName, id, fields: { [field]: typed(field, input.value, info.type) } },
          ]);
        };
      }
    }
    // outgoing flows
    const out = lane.edges.filter((e) => e.source === id);
    if (out.length || node.kind !== "end") el("div", { class: "props-section" }, body, "Flows out");
    for (const e of out) {
      const r = el("div", { class: "flow", "data-target": e.target }, body);
      el("span", {}, r, `→ ${e.target}`);
      if (node.kind === "decision") {
        this.codeInput(
          r,
          "guard",
          guardOf(node, e),
          laneName,
          (text) => {
            void this.edit([{ op: "set_guard", lane: laneName, source: id, target: e.target, guard: text.trim() }]);
          },
          { "data-target": e.target, placeholder: GUARD_PLACEHOLDER },
        );
      }
      const x = this.button(
        r,
        "disconnect",
        "×",
        () => void this.edit([{ op: "disconnect", lane: laneName, source: id, target: e.target }]),
        "small",
      );
      x.dataset.target = e.target;
      x.title = `remove the flow to ${e.target}`;
    }
    const actions = el("div", { class: "actions" }, body);
    if (node.kind !== "end") {
      this.button(actions, "connect", "Connect to…", () => {
        this.connectFrom = { lane: laneName, id };
        this.host.canvas.classList.add("connecting");
        this.showNotice("hint", `Click the node that follows ${id} (Esc cancels).`, [], 5000);
      });
    }
    this.button(actions, "remove", "Delete node", () => void this.removeSelection(), "danger");
  }

  private edgeProps(body: HTMLElement, laneName: string, source: string, target: string): void {
    const lane = this.lane(laneName);
    const e = lane?.edges.find((x) => x.source === source && x.target === target);
    if (!lane || !e) return;
    const src = lane.nodes.find((n) => n.id === source);
    el("div", { class: "props-head" }, body, `flow ${source} → ${target}`);
    el("div", { class: "props-sub" }, body, `swimlane ${laneName}`);
    if (src?.kind === "decision") {
      const r = this.row(body, "guard");
      this.codeInput(
        r,
        "guard",
        src ? guardOf(src, e) : e.label,
        laneName,
        (text) => {
          void this.edit([{ op: "set_guard", lane: laneName, source, target, guard: text.trim() }]);
        },
        { "data-target": target, placeholder: GUARD_PLACEHOLDER },
      );
      el("div", { class: "hint" }, body, "a condition, or else");
    }
    const actions = el("div", { class: "actions" }, body);
    this.button(actions, "remove", "Delete flow", () => void this.removeSelection(), "danger");
  }

  private laneProps(body: HTMLElement, laneName: string): void {
    const lane = this.lane(laneName);
    if (!lane) return;
    el("div", { class: "props-head" }, body, `swimlane ${laneName}`);
    el(
      "div",
      { class: "props-sub" },
      body,
      `${lane.virtual ? "virtual: an activity that other lanes call" : `runs on the component ${lane.component ?? laneName}`} · ${lane.file}:${lane.line}`,
    );
    if (lane.virtual) {
      this.renameForm(
        body,
        "name",
        laneName,
        "new_name",
        (v) => ({ op: "rename_lane", lane: laneName, new_name: v }),
        (v) => ({ type: "lane", lane: v }),
      );
    } else {
      el(
        "div",
        { class: "hint", "data-hint": "rename" },
        body,
        `Its name is the component's: rename the component ${laneName} to rename it.`,
      );
    }
    el("div", { class: "hint" }, body, "Drag nodes from the palette into it, or click a node kind to add it here.");
    const actions = el("div", { class: "actions" }, body);
    this.button(actions, "remove-lane", "Delete swimlane", () => void this.removeSelection(), "danger");
  }

  // ------------------------------------------------------------------ components

  private implsOf(kind: string): ImplInfo[] {
    return (this.library?.implementations ?? []).filter((i) => i.kind === kind);
  }

  private newComponentProps(body: HTMLElement, implId: string): void {
    const impl = this.library?.implementations.find((i) => i.id === implId);
    if (!impl) return;
    el("div", { class: "props-head" }, body, `new ${impl.kind} · ${impl.id}`);
    if (this.info.empty) {
      el("div", { class: "hint" }, body, `features: ${Object.keys(features(impl, this.library)).join(", ")}`);
      el(
        "div",
        { class: "hint", "data-hint": "no-model" },
        body,
        `A ${impl.id} can be added once there is a model: create it first (the form in the middle), then click ${impl.id} again.`,
      );
      return;
    }
    const form = el("form", { class: "new-component", novalidate: "" }, body);
    const m = this.host.model();
    const taken = new Set(m?.components.map((c) => c.name) ?? []);
    const seed = impl.aliases.find((a) => !taken.has(a));
    let n = 1;
    const base = impl.kind[0].toUpperCase() + impl.kind.slice(1);
    while (taken.has(`${base}${n}`)) n += 1;
    const name = el(
      "input",
      { name: "name", value: seed ?? `${base}${n}`, autocomplete: "off", spellcheck: "false", "data-field": "name" },
      this.row(form, "name"),
    );
    el("div", { class: "hint" }, form, `features: ${Object.keys(features(impl, this.library)).join(", ")}`);
    const settings = this.settingsForm(form, impl, {});
    el("button", { type: "submit", name: "add" }, form, "Add component");
    form.onsubmit = async (ev) => {
      ev.preventDefault();
      clearFieldErrors(form);
      const values = settings();
      if (values === null) return;
      const op: Op = { op: "add_component", name: name.value.trim(), kind: impl.kind, impl: impl.id, settings: values };
      if (await this.edit([op], form)) {
        this.sel = { type: "component", name: name.value.trim() };
        this.renderProps();
      }
    };
  }

  /** Inputs for an implementation's driver settings from its JSON Schema; returns a reader (null when invalid). */
  private settingsForm(
    parent: HTMLElement,
    impl: ImplInfo,
    current: Record<string, unknown>,
  ): () => Record<string, unknown> | null {
    const root = impl.settings_schema ?? {};
    const props = root.properties ?? {};
    const required = new Set(root.required ?? []);
    const box = el("fieldset", { class: "settings", "data-impl": impl.id }, parent);
    el("legend", {}, box, `settings of ${impl.id}`);
    const readers: [string, () => { ok: boolean; value?: unknown; why?: string }][] = [];
    if (!Object.keys(props).length) el("div", { class: "hint" }, box, "no settings");
    for (const [key, raw] of Object.entries(props)) {
      const s = resolve(raw, root);
      const r = this.row(box, key + (required.has(key) ? " *" : ""));
      const type = Array.isArray(s.type) ? s.type.find((t) => t !== "null") : s.type;
      const cur = key in current ? current[key] : s.default;
      const range =
        s.minimum !== undefined && s.maximum !== undefined
          ? `${s.minimum}..${s.maximum}`
          : s.minimum !== undefined
            ? `≥ ${s.minimum}`
            : s.maximum !== undefined
              ? `≤ ${s.maximum}`
              : "";
      const hint = [impl.settings_doc?.[key] ?? s.description ?? "", range && `range ${range}`]
        .filter(Boolean)
        .join(" · ");
      // sent: what the deployment has, what is required, and what the user changed from the default
      const keep = key in current || required.has(key);
      if (s.enum) {
        const sel = el("select", { name: `setting-${key}`, "data-field": `settings.${key}` }, r);
        el("option", { value: "" }, sel, "");
        for (const v of s.enum) el("option", { value: JSON.stringify(v) }, sel, String(v));
        if (cur !== undefined) sel.value = JSON.stringify(cur);
        const initial = sel.value;
        readers.push([
          key,
          () => ({ ok: true, value: sel.value && (keep || sel.value !== initial) ? JSON.parse(sel.value) : undefined }),
        ]);
      } else if (type === "boolean") {
        const cb = el("input", { type: "checkbox", name: `setting-${key}`, "data-field": `settings.${key}` }, r);
        cb.checked = cur === true;
        const initial = cb.checked;
        readers.push([key, () => ({ ok: true, value: keep || cb.checked !== initial ? cb.checked : undefined })]);
      } else {
        const numeric = type === "integer" || type === "number";
        const input = el(
          "input",
          { name: `setting-${key}`, autocomplete: "off", spellcheck: "false", "data-field": `settings.${key}` },
          r,
        );
        if (numeric) {
          input.type = "number";
          if (s.minimum !== undefined) input.min = String(s.minimum);
          if (s.maximum !== undefined) input.max = String(s.maximum);
          if (type === "number") input.step = "any";
        }
        const show = (x: unknown): string =>
          typeof x === "string" || typeof x === "number" ? String(x) : JSON.stringify(x);
        // the deployment's value, else the default as a placeholder (a default is not written)
        if (key in current && current[key] !== null) input.value = show(current[key]);
        else if (s.default !== undefined && s.default !== null) input.placeholder = `default ${show(s.default)}`;
        if (!input.placeholder && (type === "array" || type === "object"))
          input.placeholder = type === "array" ? "[1, 2]" : "{}";
        const initial = input.value;
        readers.push([
          key,
          () => {
            const t = input.value.trim();
            if (!t) return required.has(key) ? { ok: false, why: "is required" } : { ok: true };
            if (!keep && input.value === initial) return { ok: true }; // the default: not written
            if (numeric) {
              // the schema's own bounds, checked here before anything is sent (the server checks too)
              const v = Number(t);
              const bounds = range ? `must be ${range.replace("≥", "at least").replace("≤", "at most")}` : "";
              if (Number.isNaN(v))
                return { ok: false, why: type === "integer" ? "must be a whole number" : "must be a number" };
              if (type === "integer" && !Number.isInteger(v))
                return { ok: false, why: `must be a whole number${range ? `, ${range}` : ""}` };
              if ((s.minimum !== undefined && v < s.minimum) || (s.maximum !== undefined && v > s.maximum))
                return { ok: false, why: bounds };
              return { ok: true, value: v };
            }
            if (type === "array" || type === "object") {
              try {
                return { ok: true, value: JSON.parse(t) };
              } catch {
                return { ok: false, why: `must be JSON (${type === "array" ? "[1, 2]" : "{}"})` };
              }
            }
            return { ok: true, value: t };
          },
        ]);
      }
      if (hint) el("div", { class: "hint" }, r, hint);
    }
    return () => {
      const out: Record<string, unknown> = {};
      const wrong: Record<string, string> = {};
      for (const [key, read] of readers) {
        const { ok, value, why } = read();
        if (!ok) wrong[`settings.${key}`] = why ?? "needs a valid value";
        else if (value !== undefined) out[key] = value;
      }
      clearFieldErrors(box);
      if (Object.keys(wrong).length) {
        markFieldErrors(box, wrong);
        return null;
      }
      return out;
    };
  }

  private componentProps(body: HTMLElement, name: string): void {
    const m = this.host.model();
    const c = m?.components.find((x) => x.name === name) as
      | (ModelComponent & { settings?: Record<string, unknown> })
      | undefined;
    if (!m || !c) return;
    el("div", { class: "props-head" }, body, `${c.kind} · ${name}`);
    el("div", { class: "props-sub" }, body, `${c.impl} · ${c.service} · ${c.driver}`);
    this.renameForm(
      body,
      "name",
      name,
      "new_name",
      (v) => ({ op: "rename_component", component: name, new_name: v }),
      (v) => ({ type: "component", name: v }),
    );
    // deployment
    const dep = el("form", { class: "deployment", novalidate: "" }, body);
    el("div", { class: "props-section" }, dep, "Deployment");
    const implSel = el("select", { name: "impl" }, this.row(dep, "impl"));
    for (const i of this.implsOf(c.kind)) el("option", { value: i.id }, implSel, i.id);
    implSel.value = c.impl;
    const holder = el("div", {}, dep);
    let read = (): Record<string, unknown> | null => ({});
    const drawSettings = (): void => {
      holder.replaceChildren();
      const impl = this.library?.implementations.find((i) => i.id === implSel.value);
      if (impl) read = this.settingsForm(holder, impl, implSel.value === c.impl ? (c.settings ?? {}) : {});
    };
    drawSettings();
    implSel.onchange = drawSettings;
    implSel.dataset.field = "impl";
    // the checker's problems with this component's deployment (a pin wired twice, a setting a
    // driver refuses), each at the field it is about, as `umlbot check` prints it
    const problems = this.host.diagnostics().filter((d) => d.component === name);
    const atField = problems.filter((d) => d.field && dep.querySelector(`[data-field="${CSS.escape(d.field)}"]`));
    markDiagnostics(dep, atField);
    if (this.revealProblems) {
      // the deployment just applied has problems: show the first one (the panel may be scrolled
      // down to its Apply button); after the answer's last redraw of the panel
      queueMicrotask(() => {
        if (!this.revealProblems) return;
        this.revealProblems = false;
        this.props
          .querySelector(".deployment .field-problem, .deployment .problem")
          ?.scrollIntoView({ block: "nearest" });
      });
    }
    const title = dep.querySelector(".props-section");
    for (const d of problems.filter((x) => !atField.includes(x)).reverse()) {
      title?.after(el("div", { class: `problem ${d.severity}`, "data-severity": d.severity }, null, d.text));
    }
    el("button", { type: "submit", name: "apply-deployment" }, dep, "Apply deployment");
    dep.onsubmit = (ev) => {
      ev.preventDefault();
      clearFieldErrors(dep);
      const settings = read();
      if (settings === null) return;
      this.revealProblems = true;
      void this.edit([{ op: "set_deployment", component: name, impl: implSel.value, settings }], dep);
    };
    // ports
    el("div", { class: "props-section" }, body, "Ports");
    for (const [port, feature] of Object.entries(c.ports)) {
      const r = el("div", { class: "flow", "data-port": port }, body);
      el("span", {}, r, `${port} → ${feature}`);
      this.button(
        r,
        "remove-port",
        "×",
        () => void this.edit([{ op: "remove_port", component: name, port }]),
        "small",
      ).dataset.port = port;
    }
    const pf = el("form", { class: "inline" }, body);
    const portName = el(
      "input",
      { name: "port", placeholder: "port", autocomplete: "off", size: "8", "data-field": "port" },
      pf,
    );
    const feat = el("select", { name: "port-feature" }, pf);
    for (const f of c.features) el("option", { value: f }, feat, f);
    el("button", { type: "submit", name: "add-port" }, pf, "Add port");
    pf.onsubmit = (ev) => {
      ev.preventDefault();
      if (!portName.value.trim()) return;
      void this.edit([{ op: "add_port", component: name, port: portName.value.trim(), feature: feat.value }], pf);
    };
    // links
    el("div", { class: "props-section" }, body, "Links");
    for (const l of m.links.filter((x) => x.source.component === name || x.target.component === name)) {
      const r = el("div", { class: "flow", "data-link": l.id }, body);
      el("span", {}, r, `${l.id}: ${l.source.component}.${l.source.port} → ${l.target.component}.${l.target.port}`);
      this.button(
        r,
        "remove-link",
        "×",
        () => void this.edit([{ op: "remove_link", id: l.id }]),
        "small",
      ).dataset.link = l.id;
    }
    const others = m.components
      .filter((o) => o.name !== name)
      .flatMap((o) => Object.keys(o.ports).map((port) => `${o.name}.${port}`));
    if (!Object.keys(c.ports).length || !others.length) {
      // a link joins two ports: say what is missing instead of an empty list
      el(
        "div",
        { class: "hint", "data-hint": "link" },
        body,
        !Object.keys(c.ports).length
          ? `A link starts at a port of ${name}: add a port first (above).`
          : "No other component has a port yet: add one to link to.",
      );
    }
    const lf = el("form", { class: "inline" }, body);
    lf.hidden = !Object.keys(c.ports).length || !others.length;
    const from = el("select", { name: "link-from" }, lf);
    for (const port of Object.keys(c.ports)) el("option", { value: `${name}.${port}` }, from, `${name}.${port}`);
    el("span", {}, lf, "→");
    const to = el("select", { name: "link-to" }, lf);
    for (const o of others) el("option", { value: o }, to, o);
    el("button", { type: "submit", name: "add-link" }, lf, "Add link");
    lf.onsubmit = (ev) => {
      ev.preventDefault();
      if (!from.value || !to.value) return;
      void this.edit([{ op: "add_link", from: from.value, to: to.value }]);
    };
    const actions = el("div", { class: "actions" }, body);
    this.button(actions, "remove", "Delete component", () => void this.removeSelection(), "danger");
  }

  // ------------------------------------------------------------------ call / guard editor

  /** A one-line code input with completion (`/api/complete`) and a signature hint. */
  private codeInput(
    parent: HTMLElement,
    name: string,
    value: string,
    lane: string,
    commit: (text: string) => void,
    attrs: Record<string, string> = {},
  ): HTMLInputElement {
    const wrap = el("div", { class: "code-field" }, parent);
    const input = el("input", { name, value, class: "code", autocomplete: "off", spellcheck: "false", ...attrs }, wrap);
    const list = el("ul", { class: "completions", role: "listbox" }, wrap);
    const sig = el("div", { class: "signature" }, wrap);
    list.hidden = true;
    sig.hidden = true;
    let items: Completion[] = [];
    let active = 0;
    let answer: CompleteAnswer | null = null;
    let answered = ""; // the text the shown completions are for
    let seq = 0;
    let committed = value;
    const close = (): void => {
      list.hidden = true;
      items = [];
    };
    // The list floats over the page (fixed, under the input, or above it when the window has
    // no room below), so the panel's own height and scrolling never cut it.
    const place = (): void => {
      if (list.hidden) return;
      const r = input.getBoundingClientRect();
      // under the argument hint when it is shown (the list must not cover it), inside the window
      const under = sig.hidden ? r.bottom : Math.max(r.bottom, sig.getBoundingClientRect().bottom);
      const below = window.innerHeight - under - 8;
      const above = r.top - 8;
      const room = below >= 160 || below >= above ? below : above;
      const width = Math.min(Math.max(r.width, 260), window.innerWidth - 16);
      list.style.position = "fixed";
      list.style.left = `${Math.max(8, Math.min(r.left, window.innerWidth - width - 8))}px`;
      list.style.width = `${width}px`;
      list.style.maxHeight = `${Math.max(80, Math.min(360, room))}px`;
      if (room === below) {
        list.style.top = `${under + 2}px`;
        list.style.bottom = "";
      } else {
        list.style.top = "";
        list.style.bottom = `${window.innerHeight - r.top + 2}px`;
      }
    };
    this.props.addEventListener("scroll", place, { passive: true });
    const draw = (): void => {
      list.replaceChildren();
      items.forEach((it, i) => {
        const li = el("li", { "data-label": it.label, "data-kind": it.kind, role: "option" }, list);
        if (i === active) li.classList.add("active");
        el("span", { class: "label" }, li, it.label);
        if (it.detail) el("small", {}, li, it.detail);
        li.onpointerdown = (ev) => {
          ev.preventDefault();
          accept(i);
        };
      });
      list.hidden = items.length === 0;
      place();
      list.querySelector("li.active")?.scrollIntoView({ block: "nearest" });
    };
    const ask = async (): Promise<void> => {
      const mine = ++seq;
      const cursor = input.selectionStart ?? input.value.length;
      const text = input.value;
      const a = await this.request<CompleteAnswer>("/api/complete", { lane, text, cursor, field: name }, true);
      // an answer for text that has changed since (typed or pasted on) is stale: its replace
      // range would splice the completion into the wrong place; the change asks again
      if (mine !== seq || document.activeElement !== input || input.value !== text) return;
      answer = a;
      answered = text;
      // nothing to complete right after a closed call, a number or a string
      const prev = input.value.slice(0, cursor).trimEnd().slice(-1);
      items = /[)\]0-9'"]/.test(prev) ? [] : (a?.items ?? []);
      active = 0;
      draw();
      const s = a?.signature;
      if (s) {
        sig.replaceChildren();
        el("span", {}, sig, `${s.label.split("(")[0]}(`);
        s.params.forEach((p, i) => {
          if (i) sig.append(", ");
          el(i === s.active ? "b" : "span", { "data-param": p.name }, sig, paramText(p));
        });
        sig.append(")");
        if (s.returns && s.returns !== "none") sig.append(` → ${s.returns}`);
        if (s.doc) el("div", { class: "doc" }, sig, s.doc);
        sig.hidden = false;
      } else sig.hidden = true;
      place(); // below the hint as it is now
    };
    /** The input's text and cursor once item i is accepted. */
    const accepted = (i: number): { value: string; at: number } | null => {
      const it = items[i];
      if (!it) return null;
      const text = it.insert ?? it.label;
      const cursor = input.selectionStart ?? input.value.length;
      let from = answer?.replace?.[0];
      let to = answer?.replace?.[1];
      if (from === undefined || to === undefined) {
        // replace the word being typed (after the last dot)
        const before = input.value.slice(0, cursor);
        const word = /[A-Za-z_][A-Za-z0-9_]*$/.exec(before);
        from = word ? cursor - word[0].length : cursor;
        to = cursor;
        const after = /^[A-Za-z0-9_]*/.exec(input.value.slice(cursor));
        if (after) to += after[0].length;
      }
      return { value: input.value.slice(0, from) + text + input.value.slice(to), at: from + text.length };
    };
    const accept = (i: number): void => {
      const next = accepted(i);
      if (!next) return;
      input.value = next.value;
      input.setSelectionRange(next.at, next.at);
      close();
      void ask();
    };
    let timer = 0;
    const later = (): void => {
      clearTimeout(timer);
      timer = window.setTimeout(() => void ask(), 60);
    };
    input.addEventListener("input", later);
    input.addEventListener("focus", later);
    input.addEventListener("click", later);
    input.addEventListener("keydown", (ev) => {
      if (!list.hidden && items.length && input.value !== answered) close(); // typed on: stale
      if (!list.hidden && items.length) {
        if (ev.key === "ArrowDown" || ev.key === "ArrowUp") {
          ev.preventDefault();
          active = (active + (ev.key === "ArrowDown" ? 1 : items.length - 1)) % items.length;
          draw();
          return;
        }
        // Enter on a completion that is already typed out in full commits the text, as it would
        // with the list closed: a user who typed the whole name and pressed Enter meant "done"
        const typedOut = ev.key === "Enter" && accepted(active)?.value === input.value;
        if (ev.key === "Tab" || (ev.key === "Enter" && !ev.ctrlKey && !typedOut)) {
          ev.preventDefault();
          accept(active);
          return;
        }
        if (ev.key === "Escape") {
          ev.preventDefault();
          close();
          return;
        }
      }
      if (ev.key === "Enter") {
        ev.preventDefault();
        close();
        if (input.value !== committed) {
          committed = input.value;
          commit(input.value);
        }
      } else if (ev.key === "ArrowLeft" || ev.key === "ArrowRight" || ev.key === "Home" || ev.key === "End") later();
    });
    input.addEventListener("blur", () => {
      seq++;
      close();
      sig.hidden = true;
      if (input.value !== committed) {
        committed = input.value;
        commit(input.value);
      }
    });
    return input;
  }
}

/** An implementation's features with their parameters (from the implementation, else its kind). */
function features(impl: ImplInfo, library: Library | null): Record<string, FeatureInfo | null> {
  if (!Array.isArray(impl.features)) return impl.features;
  const kind = library?.kinds[impl.kind]?.features ?? {};
  return Object.fromEntries(impl.features.map((f) => [f, kind[f] ?? null]));
}

/** The guard of a decision's branch to `e.target` as written (`else` for the else branch). */
function guardOf(node: ModelNode, e: ModelEdge): string {
  const branches = node.fields?.branches;
  if (Array.isArray(branches)) {
    for (const b of branches as Record<string, unknown>[]) {
      if (b && b.then === e.target && !("else" in b)) return typeof b.if === "string" ? b.if : "";
      if (b && b.else === e.target) return "else";
    }
  }
  return e.guard ?? e.label;
}

function fieldText(node: ModelNode, field: string): string {
  const v = node.fields?.[field];
  if (v === undefined || v === null) {
    if (!node.fields) {
      if (field === "call" && node.kind === "action") return node.label;
      if (field === "name" && node.store) return node.store;
      if (field === "signal" && node.signal) return node.signal;
    }
    return "";
  }
  return typeof v === "string" ? v : JSON.stringify(v);
}

function nextLine(lane: ModelLane, node: ModelNode): number {
  let best = Infinity;
  for (const n of lane.nodes) if (n.line > node.line && n.line < best) best = n.line;
  return best;
}

/** Show the checker's problems at the fields they are about (`data-field` = the diagnostic's
 * `field`), each as the line `umlbot check` prints. */
export function markDiagnostics(form: Element, list: Diagnostic[]): void {
  for (const d of list) {
    const msg = markField(form, d.field ?? "", d.text);
    if (!msg) continue;
    msg.classList.add("field-problem", d.severity);
    msg.dataset.severity = d.severity;
  }
}

/** Mark the field `field` (`data-field`) of `form` invalid, with `text` under it; the message, or
 * null when the form has no such field. */
function markField(form: Element, field: string, text: string): HTMLElement | null {
  const input = form.querySelector<HTMLElement>(`[data-field="${CSS.escape(field)}"]`);
  if (!input) return null;
  input.setAttribute("aria-invalid", "true");
  input.classList.add("invalid");
  const msg = document.createElement("div");
  msg.className = "field-error";
  msg.dataset.field = field;
  msg.textContent = text;
  const row = input.closest(".row");
  if (row) row.append(msg);
  else input.after(msg); // right under (or beside) the field it is about
  return msg;
}

/** Remove the marks `markFieldErrors` left in `form`. */
export function clearFieldErrors(form: Element): void {
  for (const e of form.querySelectorAll(".field-error")) e.remove();
  for (const e of form.querySelectorAll("[aria-invalid]")) {
    e.removeAttribute("aria-invalid");
    e.classList.remove("invalid");
  }
}

/** Mark each field of `form` named in `fields` (`data-field`) invalid with its message under it
 * (`gpio: must be 0..27`); true when every problem found its field. */
export function markFieldErrors(form: Element, fields: Record<string, string>): boolean {
  let all = true;
  let first: HTMLElement | null = null;
  for (const [field, why] of Object.entries(fields)) {
    const input = form.querySelector<HTMLElement>(`[data-field="${CSS.escape(field)}"]`);
    if (!input) {
      all = false;
      continue;
    }
    const label = input.dataset.label ?? field.split(".").pop() ?? field;
    // the compiler's own line (`file:line:col: error: …`) as it is; a word of ours with the field's name
    markField(form, field, /:\d+:\d+: (error|warning): /.test(why) ? why : `${label}: ${why}`);
    first ??= input;
  }
  first?.focus();
  return all;
}
