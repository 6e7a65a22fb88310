// The component library (`GET /api/library`): an implementation's features and how a feature's
// signature is written. Pure (test/library.test.ts).

import type { FeatureInfo, ImplInfo, Library, ParamInfo } from "./types";

/** An implementation's features with their parameters (from the implementation, else its kind). */
export function features(impl: ImplInfo, library: Library | null): Record<string, FeatureInfo | null> {
  if (!Array.isArray(impl.features)) return impl.features;
  const kind = library?.kinds[impl.kind]?.features ?? {};
  return Object.fromEntries(impl.features.map((f) => [f, kind[f] ?? null]));
}

/** The implementations of a component kind. */
export function implsOf(library: Library | null, kind: string): ImplInfo[] {
  return (library?.implementations ?? []).filter((i) => i.kind === kind);
}

/** A feature as it is called: `name(p: type lo..hi unit, …) → returns`. */
export function signatureText(name: string, f: FeatureInfo): string {
  const ret = f.returns && f.returns !== "none" ? ` → ${f.returns}` : "";
  return f.params === null ? `${name}${ret}` : `${name}(${f.params.map(paramText).join(", ")})${ret}`;
}

/** A parameter: `name: type lo..hi unit` (its range as far as it is bounded). */
export function paramText(p: ParamInfo): string {
  let s = p.name;
  if (p.type) s += `: ${p.type}`;
  const lo = p.minimum ?? null;
  const hi = p.maximum ?? null;
  if (lo !== null && hi !== null) s += ` ${lo}..${hi}`;
  else if (lo !== null) s += ` ≥ ${lo}`;
  else if (hi !== null) s += ` ≤ ${hi}`;
  if (p.unit) s += ` ${p.unit}`;
  return s;
}
