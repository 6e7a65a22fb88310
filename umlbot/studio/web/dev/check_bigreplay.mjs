// Dev: a 100 000-event replay of the 2 000-node model: time to ready, scrub time (not shipped).
import { openPage } from "./browser.mjs";

const [url] = process.argv.slice(2);
const { browser, page } = await openPage({ width: 1600, height: 1000 });
const t0 = Date.now();
await page.goto(`${url}#diagram=activity-all`);
await page.waitForFunction("window.__studio.ready === true", null, { timeout: 120000 });
console.log("ready", Date.now() - t0, "ms");
await page.waitForTimeout(1000);
for (const t of [25, 10, 49.9, 0.5, 30]) {
  const ms = await page.evaluate((t) => {
    const a = performance.now();
    const i = document.querySelector("#replay-time");
    i.value = String(t);
    i.dispatchEvent(new Event("input"));
    return new Promise((res) => requestAnimationFrame(() => setTimeout(() => res(performance.now() - a), 0)));
  }, t);
  console.log(
    "scrub",
    t,
    "->",
    Math.round(ms),
    "ms incl. paint",
    await page.evaluate(() => document.querySelector("#replay-clock").textContent),
  );
}
await page.click("#replay-play");
await page.evaluate("window.__studio.frames.length = 0");
await page.waitForTimeout(3000);
console.log(
  "playing frames",
  await page.evaluate(() => {
    const f = window.__studio.frames;
    return [f.length, Math.max(...f)];
  }),
);
await browser.close();
