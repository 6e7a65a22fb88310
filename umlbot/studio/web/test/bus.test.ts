import assert from "node:assert/strict";
import { test } from "node:test";
import { EventBus } from "../src/core/bus";

interface Events {
  said: (text: string) => void;
  ask: (n: number) => number | undefined;
}

test("every listener hears an event, in the order they were added", () => {
  const bus = new EventBus<Events>();
  const heard: string[] = [];
  bus.on("said", (t) => heard.push(`1:${t}`));
  bus.on("said", (t) => heard.push(`2:${t}`));
  bus.emit("said", "hi");
  assert.deepEqual(heard, ["1:hi", "2:hi"]);
});

test("a request is answered by the first listener that answers; undefined when none does", () => {
  const bus = new EventBus<Events>();
  assert.equal(bus.request("ask", 1), undefined);
  const asked: number[] = [];
  bus.on("ask", (n) => {
    asked.push(n);
    return undefined; // passes
  });
  bus.on("ask", (n) => n * 2);
  bus.on("ask", () => {
    throw new Error("never asked: answered before");
  });
  assert.equal(bus.request("ask", 21), 42);
  assert.deepEqual(asked, [21]);
});

test("a removed listener hears no more; one added while an event is told hears the next one", () => {
  const bus = new EventBus<Events>();
  const heard: string[] = [];
  const off = bus.on("said", (t) => heard.push(`a:${t}`));
  bus.on("said", (t) => {
    heard.push(`b:${t}`);
    if (t === "1") bus.on("said", (u) => heard.push(`c:${u}`));
  });
  bus.emit("said", "1");
  off();
  bus.emit("said", "2");
  assert.deepEqual(heard, ["a:1", "b:1", "b:2", "c:2"]);
});
