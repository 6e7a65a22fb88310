// The stereo camera's depth picture from a component's retained state (docs/stereo.md): which
// state carries one, and its grey bytes as RGBA for a canvas. Pure: no DOM.

export interface DepthPicture {
  component: string;
  width: number;
  height: number;
  base64: string;
}

/** The first component whose state carries a depth picture (by name, for a stable choice). */
export function findDepthPicture(states: Iterable<[string, unknown]>): DepthPicture | null {
  const found: DepthPicture[] = [];
  for (const [component, state] of states) {
    if (!state || typeof state !== "object") continue;
    const s = state as { depth_image?: unknown; depth_size?: unknown };
    if (typeof s.depth_image !== "string" || !Array.isArray(s.depth_size)) continue;
    const [width, height] = s.depth_size as unknown[];
    if (typeof width !== "number" || typeof height !== "number" || width <= 0 || height <= 0) continue;
    found.push({ component, width, height, base64: s.depth_image });
  }
  found.sort((a, b) => (a.component < b.component ? -1 : a.component > b.component ? 1 : 0));
  return found[0] ?? null;
}

/** Grey bytes (near = bright, 0 = no reading) as RGBA: no reading drawn dark blue, the rest in
 * grey; null when the bytes do not fill width x height. */
export function depthRgba(grey: Uint8Array, width: number, height: number): Uint8ClampedArray<ArrayBuffer> | null {
  if (grey.length !== width * height) return null;
  const rgba = new Uint8ClampedArray(new ArrayBuffer(width * height * 4));
  for (let i = 0; i < grey.length; i++) {
    const v = grey[i];
    const o = i * 4;
    if (v === 0) {
      rgba[o] = 20;
      rgba[o + 1] = 30;
      rgba[o + 2] = 60;
    } else {
      rgba[o] = v;
      rgba[o + 1] = v;
      rgba[o + 2] = v;
    }
    rgba[o + 3] = 255;
  }
  return rgba;
}

/** base64 text as bytes. */
export function decodeBase64(text: string): Uint8Array {
  const raw = atob(text);
  const bytes = new Uint8Array(raw.length);
  for (let i = 0; i < raw.length; i++) bytes[i] = raw.charCodeAt(i);
  return bytes;
}
