// Dev: open the page in Chromium and take screenshots (not shipped).
//   node dev/shot.mjs URL OUT.png [waitMs] [--eval JS]
import { chromium } from "playwright-core";

const [url, out, wait = "3000", ...rest] = process.argv.slice(2);
const browser = await chromium.launch({
  executablePath: "/usr/bin/chromium",
  args: [
    "--no-sandbox",
    "--disable-gpu",
    "--disable-background-networking",
    "--disable-component-update",
    "--disable-sync",
  ],
});
const page = await browser.newPage({ viewport: { width: 1600, height: 950 } });
page.on("console", (m) => console.log("console:", m.type(), m.text()));
page.on("pageerror", (e) => console.log("pageerror:", e.message));
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
