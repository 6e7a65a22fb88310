// The one-line editor of a call or a guard: completion from the studio (`/api/complete`: the
// model's components, their features, the builtins), and the called feature's signature with the
// argument being typed. The text is sent on Enter or when the field is left.

import { el } from "../../core/dom";
import { paramText } from "../../model/library";
import type { CompleteAnswer, Completion } from "../../model/types";
import { accept, offersAfter } from "./completion";
import type { Panel } from "./panel";

/** A one-line code input with completion and a signature hint; `commit` gets the text to send. */
export function codeInput(
  panel: Panel,
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
  panel.el.addEventListener("scroll", place, { passive: true });
  const draw = (): void => {
    list.replaceChildren();
    items.forEach((it, i) => {
      const li = el("li", { "data-label": it.label, "data-kind": it.kind, role: "option" }, list);
      if (i === active) li.classList.add("active");
      el("span", { class: "label" }, li, it.label);
      if (it.detail) el("small", {}, li, it.detail);
      li.onpointerdown = (ev) => {
        ev.preventDefault();
        take(i);
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
    const a = await panel.studio.api.request<CompleteAnswer>(
      "/api/complete",
      { lane, text, cursor, field: name },
      true,
    );
    // an answer for text that has changed since (typed or pasted on) is stale: its replace
    // range would splice the completion into the wrong place; the change asks again
    if (mine !== seq || document.activeElement !== input || input.value !== text) return;
    answer = a;
    answered = text;
    // nothing to complete right after a closed call, a number or a string
    items = offersAfter(input.value.slice(0, cursor)) ? (a?.items ?? []) : [];
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
    return accept(input.value, input.selectionStart ?? input.value.length, it, answer?.replace);
  };
  const take = (i: number): void => {
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
        take(active);
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
