// Dev: which flows of a diagram cross, read from the drawn SVG, and a screenshot (not shipped).
//   node dev/crossing_pairs.mjs URL DIAGRAM OUT.png
import { openPage } from "./browser.mjs";

const [url, diagram = "activity-main", out = "/tmp/shot.png"] = process.argv.slice(2);
const { browser, page } = await openPage({ width: 1600, height: 1000 });
await page.goto(`${url}#diagram=${diagram}`);
await page.waitForFunction("window.__studio && window.__studio.ready === true");
await page.waitForFunction(`window.__studio.quality('${diagram}') !== null`);
console.log(JSON.stringify(await page.evaluate(`window.__studio.quality('${diagram}')`)));
const pairs = await page.evaluate((d) => {
  const pts = (s) =>
    [...s.matchAll(/([MLQ])\s*([-\d.e]+)[ ,]+([-\d.e]+)(?:\s+([-\d.e]+)[ ,]+([-\d.e]+))?/g)].map((m) =>
      m[1] === "Q" ? { x: +m[4], y: +m[5] } : { x: +m[2], y: +m[3] },
    );
  const o = (p, q, r) => (q.x - p.x) * (r.y - p.y) - (q.y - p.y) * (r.x - p.x);
  const cr = (a, b, c, e) => {
    const d1 = o(c, e, a),
      d2 = o(c, e, b),
      d3 = o(a, b, c),
      d4 = o(a, b, e);
    return ((d1 > 0 && d2 < 0) || (d1 < 0 && d2 > 0)) && ((d3 > 0 && d4 < 0) || (d3 < 0 && d4 > 0));
  };
  const svg = document.querySelector(`svg[data-diagram="${d}"]`);
  const res = [];
  for (const lane of svg.querySelectorAll("g.lane")) {
    const es = [...lane.querySelectorAll("g.edge")].map((e) => ({
      id: e.dataset.edge ?? e.id,
      s: e.dataset.source,
      t: e.dataset.target,
      p: pts(e.querySelector("path.line")?.getAttribute("d") ?? ""),
    }));
    for (let i = 0; i < es.length; i++)
      for (let j = i + 1; j < es.length; j++) {
        const a = es[i].p,
          b = es[j].p;
        for (let p = 1; p < a.length; p++)
          for (let q = 1; q < b.length; q++)
            if (cr(a[p - 1], a[p], b[q - 1], b[q]))
              res.push(
                `${es[i].s}->${es[i].t}  x  ${es[j].s}->${es[j].t}  at ${Math.round(a[p].x)},${Math.round(a[p].y)}`,
              );
      }
  }
  return res;
}, diagram);
console.log(pairs.join("\n"));
const at = process.argv[5];
if (at) {
  await page.evaluate((n) => window.__studio.reveal("RaspberryPI", n), at);
  await page.waitForTimeout(1200);
}
await page.screenshot({ path: out, fullPage: false });
await browser.close();
