// How a run of the editor is told to a modeller who is not a programmer: plain words, no
// program's jargon (no "interrupted", "orchestrator", "sim seconds per wall second").

import type { RunMsg } from "../../model/types";

/** A run's speed in words: 2 → "twice as fast as real time". */
export function speedWords(speed: number): string {
  if (speed === 1) return "real time";
  if (speed === 2) return "twice as fast as real time";
  if (speed > 1) return `${speed} times as fast as real time`;
  if (speed === 0.5) return "half as fast as real time";
  return `${speed} × real time`;
}

/** A motor service's safety stop (its `stop_reason`) in a modeller's words. */
export function safetyStopWords(reason: string): string {
  switch (reason) {
    case "watchdog":
      return "no command came in time, so its watchdog stopped it";
    case "orchestrator unresponsive":
      return "the running model stopped answering, so it stopped itself";
    case "orchestrator offline":
      return "the running model went away, so it stopped itself";
    case "deadman":
      return "its driver stopped renewing it, so the deadman stopped it";
    default:
      return `it stopped itself (${reason})`;
  }
}

/** Why the car stood still: each motor that a safety stop stopped ("" when none did). */
export function standStillText(r: NonNullable<RunMsg["result"]>): string {
  const stops = Object.entries(r.safety_stops ?? {}).sort(([a], [b]) => a.localeCompare(b));
  if (stops.length) {
    return `The car stood still because a safety stop stopped its motors: ${stops
      .map(([component, reason]) => `${component}: ${safetyStopWords(reason)}`)
      .join("; ")}.`;
  }
  return r.stood_still ? `The car stood still because its motors were stopped: ${r.stood_still}.` : "";
}

/** How a run ended: what happened, then how long the car drove in the simulation, how far, and
 * whether it hit anything. */
export function runEndText(r: NonNullable<RunMsg["result"]>): string {
  const figures = [
    r.sim_s !== undefined ? `${r.sim_s.toFixed(1)} s of simulated driving` : "",
    r.distance_m !== undefined ? `${r.distance_m.toFixed(2)} m driven` : "",
    r.collisions
      ? `hit a wall ${r.collisions === 1 ? "once" : `${r.collisions} times`}`
      : r.sim_s !== undefined
        ? "no collisions"
        : "",
  ]
    .filter(Boolean)
    .join(", ");
  const after = figures ? ` (${figures})` : "";
  const why = r.failure ? `: ${r.failure}` : "";
  switch (r.reason) {
    case "goal":
      return `The car reached the goal${after}.`;
    case "collision":
      return `The run stopped because the car hit a wall${after}.`;
    case "timeout":
      return r.failure
        ? `The run stopped because the computer could not simulate fast enough${after}: try a lower speed.`
        : `Time is up: the car did not reach the goal in time${after}.`;
    case "interrupted":
      return `You stopped the run${after}.`;
    case "orchestrator ended":
      return `The model came to its end${after}.`;
    case "orchestrator failed":
      return `The model stopped with a problem${why}; the motors were stopped${after}.`;
    case "service failed":
      return `A simulated part of the robot stopped working${why}${after}.`;
    case "failed":
      return `The run could not start${why}.`;
    default:
      return r.goal_reached ? `The car reached the goal${after}.` : `The run ended${why}${after}.`;
  }
}
