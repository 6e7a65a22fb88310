// The page's WebSocket to the studio (`/ws`, contract: docs/studio.md): it connects at the start,
// connects again after a close (back-off 0.5 s doubling to 5 s), says how the connection is
// (#connection), and hands each message to the bus as "server.<type>".

import { $ } from "../../core/dom";
import type { Bus } from "../../core/events";
import type { Studio } from "../../core/studio";
import type { ServerMsg } from "../../model/types";

/** The close code of a page the studio dropped for falling behind (umlbot/studio/hub.py). */
const CLOSE_TOO_SLOW = 4000;

export function install({ bus }: Studio): void {
  const connEl = $<HTMLElement>("#connection");
  let ws: WebSocket | null = null;
  let retry = 500;

  const connect = (): void => {
    const url = `${location.protocol === "https:" ? "wss" : "ws"}://${location.host}/ws`;
    const sock = new WebSocket(url);
    ws = sock;
    sock.onopen = () => {
      retry = 500;
      connEl.dataset.state = "open";
      connEl.textContent = "● connected";
    };
    sock.onmessage = (ev) => {
      let msg: ServerMsg;
      try {
        msg = JSON.parse(ev.data as string) as ServerMsg;
      } catch (err) {
        console.error("studio: bad frame", err);
        return;
      }
      dispatch(bus, msg);
    };
    sock.onclose = (ev) => {
      if (ws !== sock) return;
      connEl.dataset.state = "closed";
      // the studio drops a page that fell behind (CLOSE_TOO_SLOW) and says why: the page starts
      // again from a fresh hello and snapshot
      const why = ev.code === CLOSE_TOO_SLOW && ev.reason ? ev.reason : "disconnected";
      connEl.dataset.closeCode = String(ev.code);
      connEl.textContent = `○ ${why} — reconnecting…`;
      connEl.title = ev.reason || "";
      setTimeout(connect, retry);
      retry = Math.min(retry * 2, 5000);
    };
  };

  // a fresh hello (the server's working copy), e.g. after a stale edit
  bus.on("session.resync", () => ws?.close());
  bus.on("studio.start", connect);
  connEl.dataset.state = "closed";
  connEl.textContent = "○ connecting…";
}

function dispatch(bus: Bus, msg: ServerMsg): void {
  switch (msg.type) {
    case "hello":
      bus.emit("server.hello", msg);
      break;
    case "events":
      bus.emit("server.events", msg);
      break;
    case "world":
      bus.emit("server.world", msg);
      break;
    case "files":
      bus.emit("server.files", msg);
      break;
    case "conflict":
      bus.emit("server.conflict", msg);
      break;
    case "run":
      bus.emit("server.run", msg);
      break;
    case "robot":
      bus.emit("server.robot", msg);
      break;
    case "model":
      bus.emit("server.model", msg);
      break;
    default:
      break;
  }
}
