// Problems shown at the form fields they are about (`data-field`): a refused edit's, a settings
// form's own check, the checker's deployment problems.

import type { Diagnostic } from "../model/types";

/** Mark the field `field` of `form` invalid, with `text` under it; the message, or null when the
 * form has no such field. */
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

/** Remove the marks `markFieldErrors` left in `form`. */
export function clearFieldErrors(form: Element): void {
  for (const e of form.querySelectorAll(".field-error")) e.remove();
  for (const e of form.querySelectorAll("[aria-invalid]")) {
    e.removeAttribute("aria-invalid");
    e.classList.remove("invalid");
  }
}

/** Mark each field of `form` named in `fields` invalid with its message under it
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
