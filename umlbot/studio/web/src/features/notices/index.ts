// The notice bar over the canvas (#notice): one notice at a time, what happened and the user's
// ways out (its buttons), hidden by its × or after a while.

import { $, el } from "../../core/dom";
import type { Notice } from "../../core/events";
import type { Studio } from "../../core/studio";
import { closeWords, mayShow } from "./policy";

export function install({ bus }: Studio): void {
  const n = $<HTMLElement>("#notice");

  const show = ({ kind, text, actions = [], hideAfterMs = 0, files }: Notice): boolean => {
    if (!mayShow(kind, n.hidden ? null : (n.dataset.kind ?? ""))) return false;
    n.replaceChildren();
    n.dataset.kind = kind;
    delete n.dataset.files;
    el("span", { class: "text" }, n, text);
    for (const a of actions) {
      const b = el("button", { type: "button", "data-action": a.action }, n, a.label);
      b.onclick = () => void a.run();
      if (a.title) b.setAttribute("title", a.title);
    }
    const words = closeWords(kind);
    const close = el("button", { type: "button", "data-action": "dismiss" }, n, words.label);
    close.title = words.title;
    close.setAttribute("aria-label", words.aria);
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
    if (files) n.dataset.files = files.join(" ");
    return true;
  };

  bus.on("notice.show", show);
  bus.on("notice.hide", (kind) => {
    if (kind === undefined || n.dataset.kind === kind) n.hidden = true;
  });
}
