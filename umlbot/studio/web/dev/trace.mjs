// Dev: a Chromium timeline summary under load (not shipped). node dev/trace.mjs URL seconds
import { openPage } from "./browser.mjs";

const [url, seconds = "4"] = process.argv.slice(2);
const { browser, page } = await openPage({ width: 1600, height: 1000 });
await page.goto(url);
await page.waitForFunction("window.__studio && window.__studio.ready === true", null, { timeout: 120000 });
await page.waitForTimeout(3000);
await browser.startTracing(page, { categories: ["devtools.timeline", "disabled-by-default-devtools.timeline"] });
await page.waitForTimeout(Number(seconds) * 1000);
const buf = await browser.stopTracing();
const ev = JSON.parse(buf.toString()).traceEvents;
const sum = {};
for (const e of ev)
  if (e.ph === "X" && e.dur) {
    sum[e.name] = (sum[e.name] || 0) + e.dur / 1000;
  }
console.log(
  Object.entries(sum)
    .sort((a, b) => b[1] - a[1])
    .slice(0, 25)
    .map(([k, v]) => `${k}: ${v.toFixed(0)} ms`)
    .join("\n"),
);
await browser.close();
