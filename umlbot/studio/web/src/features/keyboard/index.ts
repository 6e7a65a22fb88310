// The page's keys: the editor's first (save, undo, delete…), then the viewer's: space plays or
// pauses a replay, f fits the diagram, l follows the robot. Keys typed into a field are the field's.

import type { Studio } from "../../core/studio";

export function install({ bus }: Studio): void {
  window.addEventListener("keydown", (ev) => {
    if (bus.request("key.edit", ev)) return;
    const t = ev.target as HTMLElement;
    if (ev.ctrlKey || ev.metaKey || ev.altKey || /^(INPUT|SELECT|TEXTAREA|BUTTON)$/.test(t.tagName)) return;
    if (ev.key === " ") {
      if (bus.request("replay.toggle")) ev.preventDefault();
    } else if (ev.key === "f") bus.emit("view.fit");
    else if (ev.key === "l") bus.emit("follow.toggle");
  });
}
