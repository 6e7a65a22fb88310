// A small model and monitor events for the unit tests.
import type { ModelView, MonitorEvent } from "../src/model/types";

/** Two activities: "main" with lanes A and B (file main.yaml), "other" with lane C (other.yaml). */
export const twoDiagrams: ModelView = {
  version: 1,
  name: "t",
  signals: [],
  components: [],
  links: [],
  diagrams: [
    {
      id: "activity-main",
      title: "main",
      file: "activities/main.yaml",
      lanes: ["A", "B"].map((name, i) => ({
        name,
        virtual: false,
        component: null,
        file: "activities/main.yaml",
        line: 1 + 10 * i,
        start: "start",
        datastores: [],
        nodes: [
          { id: "start", kind: "start", label: "start", line: 2 + 10 * i },
          { id: "a", kind: "action", label: "a", line: 4 + 10 * i },
          { id: "end", kind: "end", label: "end", line: 6 + 10 * i },
        ],
        edges: [
          { id: "1", source: "start", target: "a", label: "" },
          { id: "2", source: "a", target: "end", label: "" },
        ],
      })),
    },
    {
      id: "activity-other",
      title: "other",
      file: "activities/other.yaml",
      lanes: [
        {
          name: "C",
          virtual: true,
          component: null,
          file: "activities/other.yaml",
          line: 1,
          start: "start",
          datastores: [],
          nodes: [
            { id: "start", kind: "start", label: "start", line: 2 },
            { id: "end", kind: "end", label: "end", line: 3 },
          ],
          edges: [{ id: "1", source: "start", target: "end", label: "" }],
        },
      ],
    },
  ],
};

/** A trace event: node `node` of lane `lane` ran at `time` for `ms`. */
export function trace(lane: string, node: string, kind: string, time: number, ms = 1): MonitorEvent {
  return { type: "trace", time, lane, node, kind, duration_ms: ms, level: "info" };
}
