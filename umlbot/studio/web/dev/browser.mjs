// Dev: the Chromium that the dev scripts drive (Debian's /usr/bin/chromium, no browser download),
// with a page that prints its errors. Not shipped.
import { chromium } from "playwright-core";

export async function openPage({ width = 1600, height = 1000 } = {}) {
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
  const page = await browser.newPage({ viewport: { width, height } });
  page.on("pageerror", (e) => console.log("pageerror:", e.message));
  return { browser, page };
}
