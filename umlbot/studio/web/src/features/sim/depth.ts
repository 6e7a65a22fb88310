// The stereo camera's depth picture beside the track (a component whose state carries one).

import { decodeBase64, depthRgba, findDepthPicture } from "./depth-image";

export class DepthView {
  private figure: HTMLElement | null = null;
  private canvas: HTMLCanvasElement | null = null;
  private caption: HTMLElement | null = null;
  private last = "";
  private frames = 0;

  /** Put the (empty) view into `slot`, the row beside the track; a new track gets a new one. */
  attach(slot: HTMLElement | null): void {
    this.figure = null;
    this.canvas = null;
    this.last = "";
    if (!slot) return;
    const figure = document.createElement("figure");
    figure.id = "sim-depth";
    figure.hidden = true;
    const canvas = document.createElement("canvas");
    const caption = document.createElement("figcaption");
    figure.append(canvas, caption);
    slot.append(figure);
    this.figure = figure;
    this.canvas = canvas;
    this.caption = caption;
  }

  /** Draw the newest depth picture among the components' states, if it changed. */
  draw(states: Iterable<[string, unknown]>): void {
    if (!this.figure || !this.canvas || !this.caption) return;
    const picture = findDepthPicture(states);
    if (!picture || picture.base64 === this.last) return;
    this.last = picture.base64;
    const rgba = depthRgba(decodeBase64(picture.base64), picture.width, picture.height);
    if (!rgba) return;
    this.canvas.width = picture.width;
    this.canvas.height = picture.height;
    const ctx = this.canvas.getContext("2d");
    if (!ctx) return;
    ctx.putImageData(new ImageData(rgba, picture.width, picture.height), 0, 0);
    this.frames += 1;
    this.figure.hidden = false;
    this.figure.dataset.component = picture.component;
    this.figure.dataset.frames = String(this.frames);
    this.caption.textContent = `${picture.component} · depth (near = bright, no reading = blue)`;
  }
}
