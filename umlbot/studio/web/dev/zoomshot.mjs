// Dev: screenshot a diagram zoomed by wheel steps (not shipped). node dev/zoomshot.mjs URL OUT steps
import { openPage } from "./browser.mjs";

const [url, out, steps = "3"] = process.argv.slice(2);
const { browser, page } = await openPage({ width: 1600, height: 950 });
await page.goto(url);
await page.waitForFunction("window.__studio.ready === true");
await page.waitForTimeout(2500);
await page.mouse.move(700, 400);
for (let i = 0; i < Math.abs(Number(steps)); i++) await page.mouse.wheel(0, Number(steps) > 0 ? 100 : -100);
await page.waitForTimeout(300);
await page.screenshot({ path: out });
await browser.close();
