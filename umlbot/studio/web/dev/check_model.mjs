// Dev: a `model` frame redraws and keeps the stats; a dropped connection reconnects (not shipped).
import { openPage } from "./browser.mjs";

const [url] = process.argv.slice(2);
const { browser, page } = await openPage({ width: 1600, height: 950 });
const states = [];
await page.exposeFunction("__conn", (s) => states.push(s));
await page.addInitScript(() => {
  new MutationObserver(() => window.__conn(document.querySelector("#connection")?.dataset.state)).observe(document, {
    subtree: true,
    attributes: true,
    attributeFilter: ["data-state"],
  });
});
await page.goto(`${url}#diagram=activity-motion`);
await page.waitForFunction("window.__studio.ready === true");
const snap = () =>
  page.evaluate(() => ({
    nodes: document.querySelectorAll("g.node").length,
    svgs: document.querySelectorAll("svg.diagram").length,
    visible: [...document.querySelectorAll("svg.diagram")]
      .filter((s) => s.style.display !== "none")
      .map((s) => s.dataset.diagram),
    diags: [...document.querySelectorAll("#diagnostics li")].map((l) => l.textContent),
    marked: [...document.querySelectorAll("g.node.error")].map((g) => `${g.dataset.lane}/${g.dataset.node}`),
    count: document.querySelector('g.node[data-lane="MoveForward"][data-node="left_forward"]')?.dataset.count,
    conn: document.querySelector("#connection").dataset.state,
  }));
await page.waitForTimeout(1000);
console.log("before", JSON.stringify(await snap()));
await page.waitForTimeout(1300);
console.log("after model", JSON.stringify(await snap()));
await page.waitForTimeout(2500);
console.log("after drop+reconnect", JSON.stringify(await snap()), "conn states seen:", [...new Set(states)].join(","));
await browser.close();
