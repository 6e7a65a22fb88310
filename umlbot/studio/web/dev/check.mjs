// Dev: checks the page hooks against dev/serve.mjs (not shipped). node dev/check.mjs URL
import { openPage } from "./browser.mjs";

const [url] = process.argv.slice(2);
const { browser, page } = await openPage({ width: 1600, height: 950 });
await page.goto(url);
await page.waitForFunction("window.__studio.ready === true");
await page.waitForTimeout(2500);
const r = await page.evaluate(() => {
  const q = (s) => document.querySelector(s);
  const qa = (s) => [...document.querySelectorAll(s)];
  const node = (lane, id) => q(`g.node[data-lane="${lane}"][data-node="${id}"]`);
  const attrs = (el) =>
    el &&
    Object.fromEntries(
      [...el.attributes].filter((a) => a.name.startsWith("data-") || a.name === "class").map((a) => [a.name, a.value]),
    );
  const sl = node("Measure", "settle_left");
  return {
    list: qa("#diagram-list [data-diagram]").map((e) => e.dataset.diagram),
    visible: qa("svg.diagram")
      .filter((s) => s.style.display !== "none")
      .map((s) => s.dataset.diagram),
    settle_left: attrs(sl),
    settle_left_stats: sl?.querySelector("text.stats")?.textContent,
    measure: attrs(node("RaspberryPI", "measure")),
    center: attrs(node("Measure", "center")),
    center_value: node("Measure", "center")?.querySelector("text.value")?.textContent,
    look_left: attrs(node("Measure", "look_left")),
    look_left_title: node("Measure", "look_left")?.querySelector("title")?.textContent,
    turning_right: attrs(node("RaspberryPI", "turning_right")),
    look_ahead_main: attrs(node("RaspberryPI", "look_ahead")),
    look_right: attrs(node("Measure", "look_right")),
    edges_choose: qa('g.edge[data-lane="RaspberryPI"][data-source="choose"]').map((e) => [
      e.dataset.target,
      e.dataset.count,
      e.querySelector("text")?.textContent,
    ]),
    edge_seq: attrs(q('g.edge[data-lane="Stop"][data-source="both"][data-target="left_off"]')),
    edge_loop: attrs(q('g.edge[data-lane="RaspberryPI"][data-source="halt"][data-target="running"]')),
    lanes: qa("g.lane").map((l) => `${l.dataset.lane}:${l.querySelector("text")?.textContent}`),
    active: qa("g.node.active").map((g) => `${g.dataset.lane}/${g.dataset.node}`),
    trail: qa("g.node.trail").map((g) => `${g.dataset.lane}/${g.dataset.node}#${g.dataset.trail}`),
    comps: qa("g.component").map((g) => [
      g.dataset.component,
      g.getAttribute("class"),
      g.dataset.state,
      g.dataset.retained,
      g.querySelector("text.state")?.textContent,
    ]),
    orch: [q("#orchestrator-status").dataset.state, q("#orchestrator-status").textContent],
    conn: q("#connection").dataset.state,
    gaps: [q("#gaps").dataset.gaps, q("#gaps").hidden, q("#gaps").textContent],
    diags: qa("#diagnostics li").map((l) => l.textContent),
    calls: qa("#calls tbody tr").length,
    call0: qa("#calls tbody tr")
      .slice(0, 2)
      .map((tr) => [
        tr.dataset.component,
        tr.dataset.feature,
        tr.querySelector("td.args").textContent,
        tr.querySelector("td.result").textContent,
        tr.querySelector("td.latency").textContent,
      ]),
    replayHidden: q("#replay").hidden,
    sim: [
      qa("#sim svg").length,
      q("#sim .car")?.getAttribute("transform"),
      qa("#sim .ping").length,
      qa("#sim .wall").length,
    ],
    hooks: {
      ready: window.__studio.ready,
      applied: window.__studio.applied,
      lat: window.__studio.latencies.length,
      frames: window.__studio.frames.length,
    },
  };
});
console.log(JSON.stringify(r, null, 1));
await page.click('#diagram-list [data-diagram="components"]');
await page.waitForTimeout(300);
console.log(
  "after click:",
  await page.evaluate(() => [
    location.hash,
    [...document.querySelectorAll("svg.diagram")]
      .filter((s) => s.style.display !== "none")
      .map((s) => s.dataset.diagram),
  ]),
);
await page.screenshot({ path: "/work/wtstudio/out/check-components.png" });
await page.click('#diagram-list [data-diagram="activity-measure"]');
await page.waitForTimeout(300);
await page.screenshot({ path: "/work/wtstudio/out/check-measure.png" });
await browser.close();
