// The page's event bus: features say what happened, and ask for what they need, by an event's
// name, never by importing each other (after diagram-js's lib/core/EventBus.js, much smaller: no
// priorities; listeners are called in the order they were added, which main.ts fixes).

/** The events a bus carries: each name's listener signature (its payload; a request's answer). */
export type EventMap<E> = { [K in keyof E]: (...args: never[]) => unknown };

type Listener = (...args: unknown[]) => unknown;

export class EventBus<E extends EventMap<E>> {
  private listeners = new Map<keyof E, Listener[]>();

  /** Call `fn` on every `type` event, after the listeners added before it; returns its removal. */
  on<K extends keyof E>(type: K, fn: E[K]): () => void {
    const list = this.listeners.get(type) ?? [];
    const listener = fn as unknown as Listener;
    list.push(listener);
    this.listeners.set(type, list);
    return () => {
      const at = list.indexOf(listener);
      if (at >= 0) list.splice(at, 1);
    };
  }

  /** Tell every listener of `type` that it happened (what they return is not looked at). */
  emit<K extends keyof E>(type: K, ...args: Parameters<E[K]>): void {
    const list = this.listeners.get(type);
    if (!list) return;
    for (const fn of [...list]) fn(...args);
  }

  /** Ask the listeners of `type` in turn: the first that answers (returns anything but undefined)
   * ends the turn, and that is the answer; undefined when none answered. */
  request<K extends keyof E>(type: K, ...args: Parameters<E[K]>): ReturnType<E[K]> | undefined {
    const list = this.listeners.get(type);
    if (!list) return undefined;
    for (const fn of [...list]) {
      const answer = fn(...args);
      if (answer !== undefined) return answer as ReturnType<E[K]>;
    }
    return undefined;
  }
}
