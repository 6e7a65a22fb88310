// The fleet view (`umlbot studio MODEL --broker HUB --fleet`): every robot seen on the hub, with
// its orchestrator's state, the nodes it runs, its faults and its components; a click follows
// that robot live in the diagrams. When the studio's hello says `fleet` it polls `GET /api/fleet`
// once a second; a studio without `--fleet` has no such route and the page does not ask.

import { el } from "../../core/dom";
import type { Studio } from "../../core/studio";
import { type FleetSnapshot, fleetRows, hubLine } from "./rows";

const POLL_MS = 1000;
const STYLE = `
#fleet { border-bottom: 1px solid #ddd; padding: 4px 6px; max-height: 45vh; overflow: auto; contain: content; }
#fleet .hub { font-size: 12px; margin: 2px 0 4px; overflow-wrap: anywhere; }
#fleet .hub[data-connected="false"] { color: #b00020; font-weight: bold; }
#fleet table { border-collapse: collapse; width: 100%; font-size: 12px; }
#fleet thead { display: none; }
#fleet tbody tr { display: grid; grid-template-columns: auto 1fr auto; column-gap: 6px; cursor: pointer;
  padding: 2px 3px; border-bottom: 1px solid #eee; }
#fleet td { padding: 0; white-space: nowrap; overflow: hidden; text-overflow: ellipsis; }
#fleet td.robot { font-weight: 600; }
#fleet td.components { grid-row: 1; grid-column: 3; color: #555; }
#fleet td.running, #fleet td.faults { grid-column: 1 / -1; font-size: 11px; color: #555; }
#fleet td.running::before { content: "▸ "; }
#fleet td.faults::before { content: "faults: "; }
#fleet tbody tr:hover { background: #eef3ff; }
#fleet tr[data-followed="true"] { background: #dfe9ff; }
#fleet tr[data-healthy="false"] td.faults { color: #b00020; font-weight: 600; }
`;

export function install(studio: Studio): void {
  let started = false;
  studio.bus.on("server.hello", (hello) => {
    if (started || !hello.fleet) return; // every reconnect says hello again: one panel, one poll
    started = true;
    void start();
  });
}

async function fetchSnapshot(): Promise<FleetSnapshot | null> {
  const response = await fetch("api/fleet", { cache: "no-store" });
  if (response.status === 404) return null;
  if (!response.ok) throw new Error(`fleet: HTTP ${response.status}`);
  return (await response.json()) as FleetSnapshot;
}

async function start(): Promise<void> {
  let first: FleetSnapshot | null;
  try {
    first = await fetchSnapshot();
  } catch {
    return;
  }
  if (first === null) return;
  el("style", {}, document.head, STYLE);
  const sidebar = document.querySelector("#sidebar");
  const panel = el("section", { id: "fleet", "aria-label": "fleet" });
  sidebar?.prepend(panel);
  el("div", { class: "panel-title" }, panel, "Fleet");
  const hub = el("div", { class: "hub", role: "status" }, panel);
  const table = el("table", { id: "fleet-robots" }, panel);
  const head = el("tr", {}, el("thead", {}, table));
  for (const title of ["robot", "orchestrator", "running", "faults", "components"]) el("th", {}, head, title);
  head.lastElementChild?.replaceChildren("parts");
  const body = el("tbody", {}, table);
  let followed: string | null = first.followed;

  // one row a robot, kept from poll to poll: a cell is written only when its text changed
  const shown = new Map<string, { tr: HTMLTableRowElement; cells: HTMLTableCellElement[] }>();
  const columns = ["robot", "state", "running", "faults", "components"] as const;

  const draw = (snapshot: FleetSnapshot): void => {
    const t0 = performance.now();
    const line = hubLine(snapshot.hub, snapshot.robots.length);
    if (hub.textContent !== line) hub.textContent = line;
    hub.dataset.connected = String(snapshot.hub.connected);
    followed = snapshot.followed ?? followed;
    const rows = fleetRows(snapshot);
    let before: Element | null = body.firstElementChild;
    for (const row of rows) {
      let entry = shown.get(row.robot);
      if (entry === undefined) {
        const tr = el("tr", { "data-robot": row.robot });
        const cells = columns.map((c) => el("td", { class: c }, tr));
        tr.addEventListener("click", () => {
          void followRobot(row.robot);
        });
        entry = { tr, cells };
        shown.set(row.robot, entry);
      }
      const { tr, cells } = entry;
      columns.forEach((column, i) => {
        const text = row[column];
        if (cells[i].textContent !== text) {
          cells[i].textContent = text;
          if (column === "running" || column === "faults") cells[i].title = text;
        }
      });
      tr.dataset.healthy = String(row.healthy);
      tr.dataset.followed = String(row.robot === followed);
      if (tr !== before) body.insertBefore(tr, before);
      else before = before.nextElementSibling;
    }
    panel.dataset.drawMs = (performance.now() - t0).toFixed(2);
  };

  const followRobot = async (robot: string): Promise<void> => {
    const response = await fetch("api/fleet/follow", {
      method: "POST",
      headers: { "Content-Type": "application/json" },
      body: JSON.stringify({ robot }),
    });
    if (response.ok) {
      followed = robot;
      for (const tr of body.querySelectorAll("tr")) {
        (tr as HTMLElement).dataset.followed = String((tr as HTMLElement).dataset.robot === robot);
      }
    }
  };

  draw(first);
  window.setInterval(() => {
    fetchSnapshot()
      .then((snapshot) => {
        if (snapshot) draw(snapshot);
      })
      .catch(() => {
        hub.textContent = "the studio does not answer";
        hub.dataset.connected = "false";
      });
  }, POLL_MS);
}
