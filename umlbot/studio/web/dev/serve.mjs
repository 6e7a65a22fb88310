// Dev harness (not shipped): serves ../static and plays sample MonitorEvents over /ws following
// the page/server contract. Usage:
//   node dev/serve.mjs [--port 8765] [--mode live|replay] [--model F] [--events F.jsonl]
//                      [--speed 1] [--track] [--rate N (synthetic trace events/s, live)]

import { existsSync, readFileSync } from "node:fs";
import { createServer } from "node:http";
import { dirname, extname, join } from "node:path";
import { fileURLToPath } from "node:url";
import { WebSocketServer } from "ws";

const here = dirname(fileURLToPath(import.meta.url));
const args = Object.fromEntries(
  process.argv.slice(2).reduce((acc, a, i, all) => {
    if (a.startsWith("--")) acc.push([a.slice(2), all[i + 1] && !all[i + 1].startsWith("--") ? all[i + 1] : "1"]);
    return acc;
  }, []),
);
const port = Number(args.port ?? 8765);
const mode = args.mode ?? "live";
const speed = Number(args.speed ?? 1);
const model = JSON.parse(readFileSync(args.model ?? "/work/notes/sample/model_view.json", "utf8"));
const diagnostics = args.diagnostics ? JSON.parse(readFileSync(args.diagnostics, "utf8")) : [];
const events = readFileSync(args.events ?? "/work/notes/sample/events.jsonl", "utf8")
  .split("\n")
  .filter(Boolean)
  .map((l) => JSON.parse(l));
const staticDir = join(here, "..", "..", "static");
const track = args.track
  ? {
      name: "demo room",
      walls: [
        [
          [0, 0],
          [3, 0],
          [3, 2],
          [0, 2],
          [0, 0],
        ],
        [
          [1.5, 0.6],
          [1.5, 1.4],
        ],
      ],
      start: { x: 0.4, y: 1.0, heading_deg: 0 },
      goal: { x_min: 2.4, x_max: 2.9, y_min: 0.1, y_max: 0.6 },
      car: { length_m: 0.26, width_m: 0.16, sonar_forward_m: 0.12 },
    }
  : null;

const types = { ".html": "text/html", ".js": "text/javascript", ".css": "text/css", ".txt": "text/plain" };
const server = createServer((req, res) => {
  const url = new URL(req.url, "http://x");
  let file = url.pathname === "/" ? join(staticDir, "index.html") : null;
  if (url.pathname.startsWith("/static/")) file = join(staticDir, url.pathname.slice(8));
  if (!file || !existsSync(file) || file.includes("..")) {
    res.writeHead(404);
    res.end();
    return;
  }
  res.writeHead(200, { "content-type": types[extname(file)] ?? "application/octet-stream" });
  res.end(readFileSync(file));
});
const wss = new WebSocketServer({ server, path: "/ws" });
wss.on("connection", (ws) => {
  const send = (m) => ws.readyState === 1 && ws.send(JSON.stringify(m));
  send({
    type: "hello",
    version: 1,
    mode,
    robot: "car",
    source: "models/robot_car",
    model,
    diagnostics,
    track,
    replay: mode === "replay" ? { file: "run.jsonl", events } : null,
  });
  if (mode === "replay") return;
  let seq = 0;
  const frame = (evs) => {
    seq += 1;
    if (args.gap && seq === 3) seq += 1; // lose frame 3
    send({ type: "events", seq, events: evs, dropped: 0 });
  };
  frame([]); // snapshot (empty: we stream the run from its start)
  const t0 = events[0].time;
  const start = Date.now();
  let i = 0;
  const rate = Number(args.rate ?? 0);
  let synth = 0;
  const timer = setInterval(() => {
    const now = Date.now();
    const batch = [];
    if (rate) {
      // synthetic load: trace events with current timestamps
      const due = Math.floor(((now - start) / 1000) * rate);
      // random nodes of the model, like bench/studio.py
      const pool = model.diagrams.flatMap((d) => d.lanes.flatMap((l) => l.nodes.map((n) => [l.name, n.id, n.kind])));
      while (synth < due) {
        const [lane, node, kind] = pool[Math.floor(Math.random() * pool.length)];
        const duration = 0.5 + Math.random() * 19.5;
        batch.push({
          type: "trace",
          time: now / 1000,
          robot: "bench",
          lane,
          node,
          kind,
          duration_ms: Math.round(duration * 1000) / 1000,
          level: "info",
          detail: node,
          seq: synth + 1,
          ...(kind === "datastore" ? { value: synth } : {}),
        });
        synth++;
      }
    } else {
      const simT = ((now - start) / 1000) * speed;
      while (i < events.length && events[i].time - t0 <= simT) {
        batch.push({ ...events[i], time: events[i].time });
        i++;
      }
    }
    if (batch.length) frame(batch);
    if (track) {
      const t = (now - start) / 1000;
      const x = 1.5 + 1.1 * Math.cos(t * 0.4);
      const y = 1.0 + 0.7 * Math.sin(t * 0.4);
      const h = (Math.atan2(0.7 * Math.cos(t * 0.4), -1.1 * Math.sin(t * 0.4)) * 180) / Math.PI;
      const a = (h * Math.PI) / 180;
      send({
        type: "world",
        t,
        car: { x, y, heading_deg: h },
        servo_deg: 90,
        pings: [{ t, x0: x, y0: y, x1: x + 0.5 * Math.cos(a), y1: y + 0.5 * Math.sin(a), cm: 50 }],
        collisions: 0,
        goal: false,
      });
    }
    if (!rate && i >= events.length && !track) clearInterval(timer);
  }, 50);
  ws.on("close", () => clearInterval(timer));
  if (args.remodel) {
    setTimeout(
      () =>
        send({
          type: "model",
          model: args.remodel === "null" ? null : model,
          diagnostics: [
            {
              severity: "error",
              message: "late problem",
              file: "activities/motion.yaml",
              line: 8,
              column: 1,
              text: "activities/motion.yaml:8:1: error: late problem",
            },
          ],
        }),
      1500,
    );
  }
  if (args.drop) setTimeout(() => ws.close(), 2500);
});
server.listen(port, "127.0.0.1", () => console.log(`dev studio on http://127.0.0.1:${port}/ (${mode})`));
