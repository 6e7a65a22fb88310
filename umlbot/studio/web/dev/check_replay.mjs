// Dev: replay checks against dev/serve.mjs --mode replay (not shipped). node dev/check_replay.mjs URL
import { openPage } from "./browser.mjs";

const [url] = process.argv.slice(2);
const { browser, page } = await openPage({ width: 1600, height: 950 });
await page.goto(`${url}#diagram=activity-motion`);
await page.waitForFunction("window.__studio.ready === true");
await page.waitForTimeout(1500);
const snap = () =>
  page.evaluate(() => ({
    clock: document.querySelector("#replay-clock").textContent,
    value: document.querySelector("#replay-time").value,
    max: document.querySelector("#replay-time").max,
    visible: !document.querySelector("#replay").hidden,
    active: [...document.querySelectorAll("g.node.active")].map((g) => `${g.dataset.lane}/${g.dataset.node}`),
    measureCount: document.querySelector('g.node[data-lane="RaspberryPI"][data-node="measure"]')?.dataset.count,
    center: document.querySelector('g.node[data-lane="Measure"][data-node="center"]')?.dataset.value,
    calls: document.querySelectorAll("#calls tbody tr").length,
    orch: document.querySelector("#orchestrator-status").textContent,
    comps: [...document.querySelectorAll("g.component")]
      .map((g) => `${g.dataset.component}:${g.dataset.state}`)
      .join(","),
  }));
console.log("start", JSON.stringify(await snap()));
await page.selectOption("#replay-speed", "5");
await page.click("#replay-play");
await page.waitForTimeout(1000);
console.log("played 1s at 5x", JSON.stringify(await snap()));
await page.click("#replay-play");
const scrub = (t) =>
  page.evaluate((t) => {
    const i = document.querySelector("#replay-time");
    i.value = String(t);
    i.dispatchEvent(new Event("input"));
  }, t);
await scrub(5);
console.log("scrub 5", JSON.stringify(await snap()));
await scrub(2);
console.log("scrub 2", JSON.stringify(await snap()));
await scrub(5);
console.log("scrub 5 again", JSON.stringify(await snap()));
await page.screenshot({ path: "/work/wtstudio/out/replay-motion.png" });
await scrub(100);
console.log("scrub end", JSON.stringify(await snap()));
await browser.close();
