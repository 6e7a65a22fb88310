// Wire types of the page/server contract (docs/studio.md: "The page's data", "Editing requests").

/** A node kind: the compiler's (`node_kinds` of GET /api/library), never listed in the page. */
export type NodeKind = string;

export interface ModelNode {
  id: string;
  kind: NodeKind;
  label: string;
  line: number;
  store?: string;
  signal?: string;
  fields?: Record<string, unknown>; // editable fields as written (edit mode)
}

export interface ModelEdge {
  id: string;
  source: string;
  target: string;
  label: string;
  guard?: string;
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
  /** the message in words a modeller knows (the checker's own is `message`, `text`) */
  plain?: string;
  relpath?: string;
  lane?: string | null;
  node?: string | null;
  /** a deployment problem: the component, and the editor's field (`settings.in1`, `impl`) */
  component?: string;
  field?: string | null;
}

export interface TrackView {
  name: string;
  walls: [number, number][][];
  start: { x: number; y: number; heading_deg: number };
  goal: { x_min: number; x_max: number; y_min: number; y_max: number };
  car: { length_m: number; width_m: number; sonar_forward_m: number };
}

export interface MonitorEvent {
  type: "availability" | "call" | "state" | "signal" | "trace" | "orchestrator" | "exit" | "broker";
  time: number;
  robot?: string;
  topic?: string;
  component?: string;
  feature?: string;
  state?: string;
  impl?: string;
  /** an availability event: the driver the service runs (`auto` resolved), when its status says */
  driver?: string;
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
  // a `broker` event (the studio's connection to the broker)
  url?: string;
  connected?: boolean;
  problem?: string | null;
  attempts?: number;
  retry_in_s?: number;
  /** the broker is gone for good and not retried (why: "the run has ended: …") */
  ended?: string;
  /** a broker event's origin: "run", the simulator's own broker of a studio Run */
  source?: string;
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
  replay: { file: string; events: MonitorEvent[]; notes?: string[] } | null;
  edit?: EditInfo | null;
  /** a fleet hub (`umlbot studio --fleet`): the fleet view polls `GET /api/fleet` */
  fleet?: boolean;
}

// ---- editing (contract: /work/notes/edit-contract.md) ----

/** Positions the user chose: diagram id -> "<lane>/<node>" (or component name) -> [x, y]. */
export type LayoutMap = Record<string, Record<string, [number, number]>>;

export interface RunInfo {
  running: boolean;
  robot?: string;
  track?: TrackView | null;
  result?: {
    reason?: string;
    goal_reached?: boolean;
    collisions?: number;
    sim_s?: number;
    distance_m?: number;
    failure?: string | null;
    /** why the motors stopped before the run's end, in words (null: nothing stopped them) */
    stood_still?: string | null;
    /** component -> the safety stop its service made (watchdog, orchestrator unresponsive, …) */
    safety_stops?: Record<string, string>;
  };
}

export interface EditInfo {
  token: string;
  root: string;
  empty: boolean;
  dirty: boolean;
  version: number;
  layout: { positions?: LayoutMap } | null;
  conflict?: string[];
  model?: ModelView | null; // the model as written (also while it has errors)
  compiled?: boolean;
  diagnostics?: Diagnostic[];
  /** the files a swimlane can be added to (a block list of `lanes:`) */
  lane_files?: string[];
  run?: RunInfo;
  /** unsaved edits a previous studio kept when it quit */
  recovery?: { time: string | null; files: string[]; layout: boolean } | null;
}

export interface ParamInfo {
  name: string;
  type?: string;
  minimum?: number | null;
  maximum?: number | null;
  unit?: string | null;
}
export interface FeatureInfo {
  params: ParamInfo[] | null;
  returns?: string | null;
  doc?: string;
}
export interface ImplInfo {
  id: string;
  kind: string;
  service?: string;
  title?: string;
  features: Record<string, FeatureInfo> | string[];
  aliases: string[];
  settings_schema: JsonSchema | null;
  settings_doc?: Record<string, string>;
  doc?: string;
}
export interface JsonSchema {
  type?: string | string[];
  properties?: Record<string, JsonSchema>;
  required?: string[];
  title?: string;
  description?: string;
  default?: unknown;
  minimum?: number;
  maximum?: number;
  enum?: unknown[];
  items?: JsonSchema;
  anyOf?: JsonSchema[];
  $ref?: string;
  $defs?: Record<string, JsonSchema>;
}
export interface FieldInfo {
  type?: string;
  required?: boolean;
  doc?: string;
}
export interface Library {
  kinds: Record<string, { features: Record<string, FeatureInfo>; doc?: string }>;
  implementations: ImplInfo[];
  builtins: ({ name: string } & FeatureInfo)[];
  node_kinds: Record<string, { fields: Record<string, FieldInfo>; doc?: string }>;
  expression_help?: unknown;
}

export interface EditAnswer {
  version: number;
  model: ModelView | null;
  compiled?: boolean;
  diagnostics: Diagnostic[];
  lane_files?: string[];
  changed?: string[];
  dirty: boolean;
  layout?: { positions?: LayoutMap } | null;
  /** what this step renamed (an undo names it back) */
  renamed?: Renamed[];
}

export interface Renamed {
  kind: "node" | "lane" | "component";
  old: string;
  new: string;
  lane?: string | null;
}

export interface Completion {
  label: string;
  kind: string;
  detail?: string;
  insert?: string;
}
export interface Signature {
  label: string;
  params: ParamInfo[];
  active: number;
  returns?: string;
  doc?: string;
}
export interface CompleteAnswer {
  items: Completion[];
  signature: Signature | null;
  replace?: [number, number];
}

export interface FilesMsg {
  type: "files";
  reason: string;
  changed: string[];
  model: ModelView | null;
  diagnostics: Diagnostic[];
  lane_files?: string[];
  version: number;
  dirty?: boolean;
  layout?: { positions?: LayoutMap } | null;
}
export interface ConflictMsg {
  type: "conflict";
  changed: string[];
  version?: number;
}
export interface RunMsg extends RunInfo {
  type: "run";
  state: string;
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

/** The studio follows another robot id from now on (the model was created or renamed). */
export interface RobotMsg {
  type: "robot";
  robot: string;
}

export type ServerMsg = HelloMsg | EventsMsg | WorldMsg | ModelMsg | FilesMsg | ConflictMsg | RunMsg | RobotMsg;

/** An editing operation (`POST /api/edit`'s `ops`: docs/studio.md, "Editing requests"). */
export type Op = Record<string, unknown> & { op: string };
