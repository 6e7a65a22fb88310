// Wire types of the page/server contract (docs: /work/notes/studio-protocol.md, v1).

export type NodeKind =
  | "start" | "end" | "action" | "datastore" | "decision" | "fork" | "join" | "send" | "accept";

export interface ModelNode {
  id: string;
  kind: NodeKind;
  label: string;
  line: number;
  store?: string;
  signal?: string;
}

export interface ModelEdge {
  id: string;
  source: string;
  target: string;
  label: string;
}

export interface ModelLane {
  name: string;
  virtual: boolean;
  component: string | null;
  file: string;
  line: number;
  start: string;
  datastores: string[];
  nodes: ModelNode[];
  edges: ModelEdge[];
}

export interface ModelDiagram {
  id: string;
  title: string;
  file: string;
  lanes: ModelLane[];
}

export interface ModelComponent {
  name: string;
  kind: string;
  impl: string;
  service: string;
  driver: string;
  features: string[];
  ports: Record<string, string>;
}

export interface ModelLink {
  id: string;
  source: { component: string; port: string };
  target: { component: string; port: string };
}

export interface ModelView {
  version: number;
  name: string;
  signals: unknown[];
  components: ModelComponent[];
  links: ModelLink[];
  diagrams: ModelDiagram[];
}

export interface Diagnostic {
  severity: "error" | "warning";
  message: string;
  file: string;
  line: number;
  column: number;
  text: string;
}

export interface TrackView {
  name: string;
  walls: [number, number][][];
  start: { x: number; y: number; heading_deg: number };
  goal: { x_min: number; x_max: number; y_min: number; y_max: number };
  car: { length_m: number; width_m: number; sonar_forward_m: number };
}

export interface MonitorEvent {
  type: "availability" | "call" | "state" | "signal" | "trace" | "orchestrator" | "exit";
  time: number;
  robot?: string;
  topic?: string;
  component?: string;
  feature?: string;
  state?: string;
  impl?: string;
  args?: unknown;
  id?: string;
  ok?: boolean;
  value?: unknown;
  error?: string;
  latency_ms?: number;
  lane?: string;
  node?: string;
  kind?: string;
  duration_ms?: number;
  level?: string;
  detail?: string;
  payload?: unknown;
  seq?: number;
}

export interface HelloMsg {
  type: "hello";
  version: number;
  mode: "live" | "replay";
  robot: string;
  source: string;
  model: ModelView | null;
  diagnostics: Diagnostic[];
  track: TrackView | null;
  replay: { file: string; events: MonitorEvent[] } | null;
}

export interface EventsMsg {
  type: "events";
  seq: number;
  events: MonitorEvent[];
  dropped: number;
}

export interface Ping {
  t: number;
  x0: number;
  y0: number;
  x1: number;
  y1: number;
  cm: number | null;
}

export interface WorldMsg {
  type: "world";
  t: number;
  car: { x: number; y: number; heading_deg: number };
  servo_deg: number;
  pings: Ping[];
  collisions: number;
  goal: boolean;
}

export interface ModelMsg {
  type: "model";
  model: ModelView | null;
  diagnostics: Diagnostic[];
}

export type ServerMsg = HelloMsg | EventsMsg | WorldMsg | ModelMsg;
