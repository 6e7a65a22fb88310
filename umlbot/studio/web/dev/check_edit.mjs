// Dev: editing responsiveness against a running `umlbot studio FOLDER` (not shipped).
//   python bench/studio.py builds a 2 000-node folder; then: umlbot studio FOLDER --port 8765 and
//   node dev/check_edit.mjs http://127.0.0.1:8765/#diagram=activity-all ops.json [OUT.png]
// ops.json: a list of edits, each a list of operations (docs/studio.md, "Editing requests").
// Prints per edit the ms until the server answered and until the shown diagram drew the answer,
// and the frame times meanwhile (p50/p99/max).
import { readFileSync } from "node:fs";
import { openPage } from "./browser.mjs";

const [url, opsFile, out = "/tmp/check_edit.png"] = process.argv.slice(2);
const edits = JSON.parse(readFileSync(opsFile, "utf8"));
const { browser, page } = await openPage({ width: 1600, height: 1000 });
await page.goto(url);
await page.waitForFunction(
  "window.__studio && window.__studio.ready === true && window.__studio.edit && window.__studio.edit.drawn >= 0",
  null,
  { timeout: 120000 },
);
await page.evaluate(() => {
  window.__editFrames = [];
  let last = 0;
  const f = (t) => {
    if (last) window.__editFrames.push(t - last);
    last = t;
    requestAnimationFrame(f);
  };
  requestAnimationFrame(f);
});
const times = [];
for (const ops of edits) {
  times.push(
    await page.evaluate(async (ops) => {
      const t0 = performance.now();
      await window.__studio.edit.send(ops);
      const answered = performance.now() - t0;
      const v = window.__studio.edit.version;
      while (window.__studio.edit.drawn < v) await new Promise((r) => setTimeout(r, 5));
      return [Math.round(answered), Math.round(performance.now() - t0)];
    }, ops),
  );
}
const r = await page.evaluate(() => {
  const f = window.__editFrames.slice().sort((a, b) => a - b);
  const q = (p) => (f.length ? f[Math.min(f.length - 1, Math.ceil(p * f.length) - 1)] : null);
  return { frames: f.length, p50: q(0.5), p99: q(0.99), max: f[f.length - 1], errors: window.__studio.edit.errors };
});
console.log(JSON.stringify({ answered_drawn_ms: times, ...r }));
await page.screenshot({ path: out });
await browser.close();
