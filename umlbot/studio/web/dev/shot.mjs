// Dev: open the page in Chromium and take screenshots (not shipped).
//   node dev/shot.mjs URL OUT.png [waitMs] [--eval JS]
import { openPage } from "./browser.mjs";

const [url, out, wait = "3000", ...rest] = process.argv.slice(2);
const { browser, page } = await openPage({ width: 1600, height: 950 });
page.on("console", (m) => console.log("console:", m.type(), m.text()));
await page.goto(url);
await page.waitForTimeout(Number(wait));
const i = rest.indexOf("--eval");
if (i >= 0) {
  const r = await page.evaluate(rest[i + 1]);
  console.log(typeof r === "string" ? r : JSON.stringify(r, null, 1));
  await page.waitForTimeout(500);
}
await page.screenshot({ path: out });
await browser.close();
