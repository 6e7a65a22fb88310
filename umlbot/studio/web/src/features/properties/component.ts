// A component's properties (its name, deployment with the checker's problems at their fields,
// ports and links) and a new component's form (from the library: its name and settings).

import { el } from "../../core/dom";
import { clearFieldErrors, markDiagnostics } from "../../core/forms";
import { features, implsOf } from "../../model/library";
import type { ModelComponent, Op } from "../../model/types";
import { newComponentName } from "./fields";
import { button, type Panel, renameForm, row } from "./panel";
import { settingsForm } from "./settings";

export function newComponentProps(panel: Panel, body: HTMLElement, implId: string): void {
  const { store } = panel.studio;
  const library = panel.edit.library;
  const impl = library?.implementations.find((i) => i.id === implId);
  if (!impl) return;
  el("div", { class: "props-head" }, body, `new ${impl.kind} · ${impl.id}`);
  const featureList = `features: ${Object.keys(features(impl, library)).join(", ")}`;
  if (panel.edit.info.empty) {
    el("div", { class: "hint" }, body, featureList);
    el(
      "div",
      { class: "hint", "data-hint": "no-model" },
      body,
      `A ${impl.id} can be added once there is a model: create it first (the form in the middle), then click ${impl.id} again.`,
    );
    return;
  }
  const form = el("form", { class: "new-component", novalidate: "" }, body);
  const taken = new Set(store.model?.components.map((c) => c.name) ?? []);
  const name = el(
    "input",
    {
      name: "name",
      value: newComponentName(impl, taken),
      autocomplete: "off",
      spellcheck: "false",
      "data-field": "name",
    },
    row(form, "name"),
  );
  el("div", { class: "hint" }, form, featureList);
  const settings = settingsForm(form, impl, {});
  el("button", { type: "submit", name: "add" }, form, "Add component");
  form.onsubmit = async (ev) => {
    ev.preventDefault();
    clearFieldErrors(form);
    const values = settings();
    if (values === null) return;
    const op: Op = { op: "add_component", name: name.value.trim(), kind: impl.kind, impl: impl.id, settings: values };
    if (await panel.send([op], form)) {
      panel.edit.selection = { type: "component", name: name.value.trim() };
      panel.render();
    }
  };
}

export function componentProps(panel: Panel, body: HTMLElement, name: string): void {
  const { bus, store } = panel.studio;
  const m = store.model;
  const c = m?.components.find((x) => x.name === name) as
    | (ModelComponent & { settings?: Record<string, unknown> })
    | undefined;
  if (!m || !c) return;
  el("div", { class: "props-head" }, body, `${c.kind} · ${name}`);
  el("div", { class: "props-sub" }, body, `${c.impl} · ${c.service} · ${c.driver}`);
  renameForm(
    panel,
    body,
    "name",
    name,
    "new_name",
    (v) => ({ op: "rename_component", component: name, new_name: v }),
    (v) => ({ type: "component", name: v }),
  );
  deployment(panel, body, c);
  // ports
  el("div", { class: "props-section" }, body, "Ports");
  for (const [port, feature] of Object.entries(c.ports)) {
    const r = el("div", { class: "flow", "data-port": port }, body);
    el("span", {}, r, `${port} → ${feature}`);
    button(
      r,
      "remove-port",
      "×",
      () => void panel.send([{ op: "remove_port", component: name, port }]),
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
    void panel.send([{ op: "add_port", component: name, port: portName.value.trim(), feature: feat.value }], pf);
  };
  // links
  el("div", { class: "props-section" }, body, "Links");
  for (const l of m.links.filter((x) => x.source.component === name || x.target.component === name)) {
    const r = el("div", { class: "flow", "data-link": l.id }, body);
    el("span", {}, r, `${l.id}: ${l.source.component}.${l.source.port} → ${l.target.component}.${l.target.port}`);
    button(r, "remove-link", "×", () => void panel.send([{ op: "remove_link", id: l.id }]), "small").dataset.link =
      l.id;
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
    void panel.send([{ op: "add_link", from: from.value, to: to.value }]);
  };
  const actions = el("div", { class: "actions" }, body);
  button(actions, "remove", "Delete component", () => bus.emit("selection.delete"), "danger");
}

/** A component's deployment: its implementation and settings, with the checker's problems with it
 * (a pin wired twice, a setting a driver refuses) each at the field it is about, as `umlbot check`
 * prints it. */
function deployment(panel: Panel, body: HTMLElement, c: ModelComponent & { settings?: Record<string, unknown> }): void {
  const { store } = panel.studio;
  const name = c.name;
  const library = panel.edit.library;
  const dep = el("form", { class: "deployment", novalidate: "" }, body);
  el("div", { class: "props-section" }, dep, "Deployment");
  const implSel = el("select", { name: "impl" }, row(dep, "impl"));
  for (const i of implsOf(library, c.kind)) el("option", { value: i.id }, implSel, i.id);
  implSel.value = c.impl;
  const holder = el("div", {}, dep);
  let read = (): Record<string, unknown> | null => ({});
  const drawSettings = (): void => {
    holder.replaceChildren();
    const impl = library?.implementations.find((i) => i.id === implSel.value);
    if (impl) read = settingsForm(holder, impl, implSel.value === c.impl ? (c.settings ?? {}) : {});
  };
  drawSettings();
  implSel.onchange = drawSettings;
  implSel.dataset.field = "impl";
  const problems = store.diagnostics.filter((d) => d.component === name);
  const atField = problems.filter((d) => d.field && dep.querySelector(`[data-field="${CSS.escape(d.field)}"]`));
  markDiagnostics(dep, atField);
  if (panel.revealProblems) {
    // the deployment just applied has problems: show the first one (the panel may be scrolled
    // down to its Apply button); after the answer's last redraw of the panel
    queueMicrotask(() => {
      if (!panel.revealProblems) return;
      panel.revealProblems = false;
      panel.el.querySelector(".deployment .field-problem, .deployment .problem")?.scrollIntoView({ block: "nearest" });
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
    panel.revealProblems = true;
    void panel.send([{ op: "set_deployment", component: name, impl: implSel.value, settings }], dep);
  };
}
