// The app context every feature receives (instead of module-level state): the bus, the store, the
// hooks, the frame loop, the canvas, the renderer and the studio's HTTP API.

import { Renderer } from "../draw/render";
import { Api } from "./api";
import { EventBus } from "./bus";
import { Canvas } from "./canvas";
import { $ } from "./dom";
import type { Bus, StudioEvents } from "./events";
import { Frames } from "./frames";
import { createHooks, type StudioHooks } from "./hooks";
import { Store } from "./store";

export interface Studio {
  bus: Bus;
  store: Store;
  hooks: StudioHooks;
  frames: Frames;
  canvas: Canvas;
  renderer: Renderer;
  /** the studio's HTTP API in edit mode */
  api: Api;
}

/** A feature: installed once, at the start, with the app context. */
export type Feature = (studio: Studio) => void;

export function createStudio(): Studio {
  const bus = new EventBus<StudioEvents>();
  const store = new Store();
  const hooks = createHooks();
  const renderer = new Renderer();
  const frames = new Frames(bus, store, hooks, renderer);
  const canvas = new Canvas($<HTMLDivElement>("#canvas"));
  const api = new Api(bus, store, hooks);
  return { bus, store, hooks, frames, canvas, renderer, api };
}
