// The inputs for an implementation's driver settings, from its JSON Schema, and their reader.

import { el } from "../../core/dom";
import { clearFieldErrors, markFieldErrors } from "../../core/forms";
import type { ImplInfo } from "../../model/types";
import { type Reading, rangeText, readSetting, resolveSchema } from "./fields";
import { row } from "./panel";

/** Draw the settings of `impl` (showing `current`, a deployment's) into `parent`; returns their
 * reader: the values to send, or null (each problem shown at its field) when one is refused. */
export function settingsForm(
  parent: HTMLElement,
  impl: ImplInfo,
  current: Record<string, unknown>,
): () => Record<string, unknown> | null {
  const root = impl.settings_schema ?? {};
  const props = root.properties ?? {};
  const required = new Set(root.required ?? []);
  const box = el("fieldset", { class: "settings", "data-impl": impl.id }, parent);
  el("legend", {}, box, `settings of ${impl.id}`);
  const readers: [string, () => Reading][] = [];
  if (!Object.keys(props).length) el("div", { class: "hint" }, box, "no settings");
  for (const [key, raw] of Object.entries(props)) {
    const s = resolveSchema(raw, root);
    const r = row(box, key + (required.has(key) ? " *" : ""));
    const type = Array.isArray(s.type) ? s.type.find((t) => t !== "null") : s.type;
    const cur = key in current ? current[key] : s.default;
    const range = rangeText(s);
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
      const input = el(
        "input",
        { name: `setting-${key}`, autocomplete: "off", spellcheck: "false", "data-field": `settings.${key}` },
        r,
      );
      if (type === "integer" || type === "number") {
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
      readers.push([key, () => readSetting(input.value, initial, s, type, required.has(key), keep)]);
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
