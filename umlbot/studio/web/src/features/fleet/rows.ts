// The fleet view's rows from `GET /api/fleet` (pure: no DOM, unit-tested).

export interface FleetRobot {
  robot: string;
  orchestrator: string;
  reason: string | null;
  nodes: Record<string, string>;
  components: Record<string, string>;
  faults: string[];
  age_s: number;
}

export interface FleetHub {
  url: string;
  connected: boolean;
  problem?: string | null;
  retry_in_s?: number;
}

export interface FleetSnapshot {
  hub: FleetHub;
  robots: FleetRobot[];
  followed: string | null;
}

export interface FleetRow {
  robot: string;
  state: string;
  running: string;
  faults: string;
  components: string;
  healthy: boolean;
}

/** One row a robot: its orchestrator's state, the nodes its lanes run, faults, components. */
export function fleetRows(snapshot: FleetSnapshot): FleetRow[] {
  return snapshot.robots.map((r) => {
    const comps = Object.entries(r.components);
    const online = comps.filter(([, s]) => s === "online").length;
    const running = Object.entries(r.nodes)
      .map(([lane, node]) => `${lane}: ${node}`)
      .join(", ");
    return {
      robot: r.robot,
      state: r.reason && r.orchestrator !== "running" ? `${r.orchestrator} (${r.reason})` : r.orchestrator,
      running: running || "–",
      faults: r.faults.length ? r.faults.join("; ") : "none",
      components: comps.length ? `${online}/${comps.length} online` : "none seen",
      healthy: r.faults.length === 0 && r.orchestrator !== "failed",
    };
  });
}

/** The line above the table: the hub, reachable or not (and why, and when it tries again). */
export function hubLine(hub: FleetHub, robots: number): string {
  if (hub.connected) return `hub ${hub.url}: ${robots} robot${robots === 1 ? "" : "s"}`;
  const why = hub.problem ? `: ${hub.problem}` : "";
  const retry = hub.retry_in_s !== undefined ? `, next attempt in ${Math.ceil(hub.retry_in_s)} s` : "";
  return `hub ${hub.url} unreachable${why}${retry} (showing what was last seen)`;
}
