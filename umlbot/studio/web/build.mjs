// Builds the page into ../static (shipped inside the Python package): `npm ci && npm run build`.
// `node build.mjs --out DIR` builds into DIR instead (`make test` compares it with ../static).

import { copyFileSync, mkdirSync, readFileSync, rmSync, writeFileSync } from "node:fs";
import { dirname, join } from "node:path";
import { fileURLToPath } from "node:url";
import { build } from "esbuild";

const here = dirname(fileURLToPath(import.meta.url));
const at = process.argv.indexOf("--out");
const out = at > 0 && process.argv[at + 1] ? process.argv[at + 1] : join(here, "..", "static");
rmSync(out, { recursive: true, force: true });
mkdirSync(out, { recursive: true });

await build({
  entryPoints: [join(here, "src", "main.ts")],
  bundle: true,
  format: "esm",
  target: "es2020",
  minify: true,
  legalComments: "none",
  outfile: join(out, "studio.js"),
  logLevel: "warning",
});
copyFileSync(join(here, "src", "style.css"), join(out, "studio.css"));
copyFileSync(join(here, "index.html"), join(out, "index.html"));
copyFileSync(join(here, "node_modules", "elkjs", "lib", "elk-worker.min.js"), join(out, "elk-worker.min.js"));

const elkPkg = JSON.parse(readFileSync(join(here, "node_modules", "elkjs", "package.json"), "utf8"));
const elkLicense = readFileSync(join(here, "node_modules", "elkjs", "LICENSE.md"), "utf8");
writeFileSync(
  join(out, "THIRD_PARTY_LICENSES.txt"),
  [
    "Third-party software in umlbot/studio/static",
    "",
    `elkjs ${elkPkg.version} (Eclipse Layout Kernel compiled to JavaScript)`,
    "  files: elk-worker.min.js (unmodified) and the elk-api part of studio.js",
    "  source: https://github.com/kieler/elkjs",
    `  license: ${elkPkg.license} (Eclipse Public License 2.0); the full text follows.`,
    "",
    elkLicense,
  ].join("\n"),
);
console.log(`built ${out}`);
