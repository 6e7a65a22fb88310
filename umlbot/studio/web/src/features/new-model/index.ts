// A folder with no model yet: the canvas offers a starter model (the car's components, their
// deployment and a main activity, start → end) under the name the user gives.

import { el } from "../../core/dom";
import { clearFieldErrors } from "../../core/forms";
import type { Studio } from "../../core/studio";
import type { EditAnswer } from "../../model/types";

export function install({ bus, store, api }: Studio): void {
  const showEmpty = (target: HTMLElement, root: string): void => {
    target.replaceChildren();
    const form = el("form", { id: "new-model-form" }, target);
    el("h2", {}, form, "This folder has no model yet");
    el(
      "p",
      {},
      form,
      `Start one in ${root}: a starter model with the car's components, their deployment and a main activity (start → end).`,
    );
    const label = el("label", { for: "model-name", class: "field-label" }, form, "Robot name");
    const name = el(
      "input",
      {
        id: "model-name",
        name: "model-name",
        placeholder: "e.g. my_robot",
        value: root.split("/").filter(Boolean).pop() ?? "my_robot",
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
      const a = await api.request<EditAnswer>("/api/new", { name: name.value.trim() }, false, form);
      btn.disabled = false;
      if (a) {
        bus.emit("edit.model-created");
        bus.emit("edit.apply", a, true);
      }
    };
  };

  bus.on("model.missing", (message) => {
    if (store.edit?.info.empty) showEmpty(message, store.edit.info.root);
  });
}
