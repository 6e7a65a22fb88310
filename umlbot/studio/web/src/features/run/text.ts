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
