// Dev: measure frames under load against dev/serve.mjs --rate N (not shipped).
//   node dev/load.mjs URL seconds OUT.png
import { openPage } from "./browser.mjs";

const [url, seconds = "8", out = "/tmp/load.png"] = process.argv.slice(2);
const { browser, page } = await openPage({ width: 1600, height: 1000 });
const t0 = Date.now();
await page.goto(url);
await page.waitForFunction("window.__studio && window.__studio.ready === true", null, { timeout: 120000 });
console.log("ready after", Date.now() - t0, "ms; nodes", await page.locator("g.node").count());
await page.evaluate("window.__studio.frames.length = 0; window.__studio.latencies.length = 0");
await page.waitForTimeout(Number(seconds) * 1000);
const r = await page.evaluate(() => {
  const f = window.__studio.frames.slice().sort((a, b) => a - b);
  const l = window.__studio.latencies.slice().sort((a, b) => a - b);
  const q = (a, p) => (a.length ? a[Math.min(a.length - 1, Math.ceil(p * a.length) - 1)] : null);
  return {
    frames: f.length,
    p50: q(f, 0.5),
    p99: q(f, 0.99),
    max: f[f.length - 1],
    over100: f.filter((x) => x > 100).length,
    lat50: q(l, 0.5),
    lat99: q(l, 0.99),
    applied: window.__studio.applied,
  };
});
console.log(JSON.stringify(r));
await page.screenshot({ path: out });
await browser.close();
