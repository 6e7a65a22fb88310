import { openPage } from "./browser.mjs";

const [url, diagram] = process.argv.slice(2);
const { browser, page } = await openPage({ width: 1600, height: 1000 });
await page.goto(`${url}#diagram=${diagram}`);
await page.waitForFunction("window.__studio && window.__studio.ready === true");
await page.waitForFunction(`window.__studio.quality('${diagram}') !== null`);
console.log(
  diagram,
  "opening",
  JSON.stringify(await page.evaluate(`window.__studio.quality('${diagram}')`)),
  await page.locator('g.node[data-kind="region"]').count(),
  "regions",
);
await page.evaluate(`window.__studio.regions('${diagram}', 'open')`);
await page.waitForFunction(
  `document.querySelectorAll('svg[data-diagram="${diagram}"] g.node[data-kind="region"]').length === 0`,
  null,
  { timeout: 30000 },
);
await page.waitForTimeout(300);
console.log(diagram, "all open", JSON.stringify(await page.evaluate(`window.__studio.quality('${diagram}')`)));
await browser.close();
