// The properties panel's pure parts: what a field shows, what a typed text sends, a settings
// field's check against its JSON Schema, a new component's name (test/properties.test.ts).

import type { ImplInfo, JsonSchema, ModelEdge, ModelLane, ModelNode } from "../../model/types";

/** Field types (the server's library) that are flows: edited by connecting nodes, never as text. */
export const FLOW_TYPES = new Set(["node", "nodes", "branches"]);
/** An empty guard's input: the output is unfinished (the checker reports it) until one is typed. */
export const GUARD_PLACEHOLDER = "type this output's guard";

/** A typed text as the value to send: numbers and booleans as such, the rest as text. */
export function typed(field: string, text: string, type: string | undefined): unknown {
  const t = text.trim();
  if (t === "") return null;
  if (field === "call" || field === "name" || field === "signal" || field === "store") return t;
  if (/^-?\d+(\.\d+)?$/.test(t) && (!type || /number|integer|float|value|any/.test(type) || field === "value"))
    return Number(t);
  if ((t === "true" || t === "false") && (!type || /bool|value|any/.test(type) || field === "value"))
    return t === "true";
  return t;
}

/** A schema with its `$ref` and `anyOf` (the first that is not null) resolved against `root`. */
export function resolveSchema(s: JsonSchema, root: JsonSchema): JsonSchema {
  let cur = s;
  for (let i = 0; i < 8; i++) {
    if (cur.$ref) {
      const name = cur.$ref.split("/").pop() ?? "";
      cur = { ...(root.$defs?.[name] ?? {}), ...cur, $ref: undefined };
      continue;
    }
    if (cur.anyOf) {
      const pick = cur.anyOf.find((x) => x.type !== "null") ?? cur.anyOf[0];
      cur = { ...pick, ...cur, anyOf: undefined, type: pick.type };
      continue;
    }
    break;
  }
  return cur;
}

/** A node's field as written (older model views without `fields`: from the label, store, signal). */
export function fieldText(node: ModelNode, field: string): string {
  const v = node.fields?.[field];
  if (v === undefined || v === null) {
    if (!node.fields) {
      if (field === "call" && node.kind === "action") return node.label;
      if (field === "name" && node.store) return node.store;
      if (field === "signal" && node.signal) return node.signal;
    }
    return "";
  }
  return typeof v === "string" ? v : JSON.stringify(v);
}

/** The guard of a decision's branch to `e.target` as written (`else` for the else branch). */
export function guardOf(node: ModelNode, e: ModelEdge): string {
  const branches = node.fields?.branches;
  if (Array.isArray(branches)) {
    for (const b of branches as Record<string, unknown>[]) {
      if (b && b.then === e.target && !("else" in b)) return typeof b.if === "string" ? b.if : "";
      if (b && b.else === e.target) return "else";
    }
  }
  return e.guard ?? e.label;
}

/** The first line after `node`'s of its lane's nodes (Infinity for the last): a problem on a line
 * from the node's up to it is the node's. */
export function nextLine(lane: ModelLane, node: ModelNode): number {
  let best = Infinity;
  for (const n of lane.nodes) if (n.line > node.line && n.line < best) best = n.line;
  return best;
}

/** A new component's name: the implementation's first seed name not taken, else `<Kind><n>`. */
export function newComponentName(impl: ImplInfo, taken: Set<string>): string {
  const seed = impl.aliases.find((a) => !taken.has(a));
  if (seed) return seed;
  let n = 1;
  const base = impl.kind[0].toUpperCase() + impl.kind.slice(1);
  while (taken.has(`${base}${n}`)) n += 1;
  return `${base}${n}`;
}

/** A setting's range as said to the user (`0..27`, `≥ 1`, `≤ 5`, or ""). */
export function rangeText(s: JsonSchema): string {
  if (s.minimum !== undefined && s.maximum !== undefined) return `${s.minimum}..${s.maximum}`;
  if (s.minimum !== undefined) return `≥ ${s.minimum}`;
  if (s.maximum !== undefined) return `≤ ${s.maximum}`;
  return "";
}

/** A setting as read from its field: its value (undefined: not written), or why it is refused. */
export interface Reading {
  ok: boolean;
  value?: unknown;
  why?: string;
}

/** A text setting's field read against its schema `s` (`type`: its type but null). `initial`: what
 * the field showed; `keep`: the deployment has it or it is required (sent even when unchanged; a
 * default the user did not change is not written). Numbers are checked against the schema's own
 * bounds before anything is sent (the server checks too). */
export function readSetting(
  raw: string,
  initial: string,
  s: JsonSchema,
  type: string | undefined,
  required: boolean,
  keep: boolean,
): Reading {
  const t = raw.trim();
  if (!t) return required ? { ok: false, why: "is required" } : { ok: true };
  if (!keep && raw === initial) return { ok: true }; // the default: not written
  const range = rangeText(s);
  if (type === "integer" || type === "number") {
    const v = Number(t);
    const bounds = range ? `must be ${range.replace("≥", "at least").replace("≤", "at most")}` : "";
    if (Number.isNaN(v)) return { ok: false, why: type === "integer" ? "must be a whole number" : "must be a number" };
    if (type === "integer" && !Number.isInteger(v)) {
      return { ok: false, why: `must be a whole number${range ? `, ${range}` : ""}` };
    }
    if ((s.minimum !== undefined && v < s.minimum) || (s.maximum !== undefined && v > s.maximum)) {
      return { ok: false, why: bounds };
    }
    return { ok: true, value: v };
  }
  if (type === "array" || type === "object") {
    try {
      return { ok: true, value: JSON.parse(t) };
    } catch {
      return { ok: false, why: `must be JSON (${type === "array" ? "[1, 2]" : "{}"})` };
    }
  }
  return { ok: true, value: t };
}
