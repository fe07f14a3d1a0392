// The browser viewer's side of GALLERY's side-by-side pairs: the same poses as the native gallery
// (docs/images/gallery2/<name>-on.json), rendered by the page in headless chromium (SwiftShader's
// WebGL2) at 1280x720, once every room round the pose has arrived.
//   GROTTO_SERVER=build/bin/grotto-server node web/e2e/gallery.mjs OUT_DIR [name...]
// writes OUT_DIR/<name>-web.png for each pose (all of them by default).
import { readFileSync, mkdirSync, writeFileSync } from "node:fs";
import { join, dirname, resolve } from "node:path";
import { fileURLToPath } from "node:url";
import { startServer, launchBrowser } from "./harness.mjs";

const root = resolve(dirname(fileURLToPath(import.meta.url)), "../..");
const out = process.argv[2];
if (!out) {
  console.error("usage: node web/e2e/gallery.mjs OUT_DIR [name...]");
  process.exit(2);
}
const names = process.argv.slice(3).length
  ? process.argv.slice(3)
  : ["hall-across-7", "hall-entrance-95", "stalactites-95", "flythrough-7", "tunnel-7", "ceiling-3"];
mkdirSync(out, { recursive: true });
const servers = new Map();
const browser = await launchBrowser();
try {
  for (const name of names) {
    const shot = JSON.parse(readFileSync(join(root, "docs/images/gallery2", `${name}-on.json`)));
    const seed = shot.seed;
    if (!servers.has(seed)) servers.set(seed, await startServer(["--seed", String(seed)]));
    const { position: [x, y, z], yaw, pitch } = shot.pose;
    const page = await browser.newPage({ viewport: { width: 1280, height: 720 } });
    const problems = [];
    page.on("console", (m) => m.type() === "error" && problems.push(m.text()));
    // fly=1: held where the pose is (walking would drop the eye to 1.6 m over the floor).
    await page.goto(`${servers.get(seed).url}/?seed=${seed}&pose=${x},${y},${z},${yaw},${pitch}&fly=1`);
    await page.waitForFunction(() => window.grotto && window.grotto.rooms_loaded >= 3, null, { timeout: 120000 });
    // Settled: nothing in flight for two seconds, and frames drawn since.
    let quiet = 0;
    for (let i = 0; i < 240 && quiet < 4; i++) {
      await page.waitForTimeout(500);
      quiet = (await page.evaluate(() => window.grotto.in_flight)) === 0 ? quiet + 1 : 0;
    }
    const f = await page.evaluate(() => window.grotto.frames);
    await page.waitForFunction((n) => window.grotto.frames >= n + 3, f, { timeout: 60000 });
    await page.evaluate(() => { for (const id of ["overlay", "help"]) document.getElementById(id).style.display = "none"; });
    await page.waitForFunction((n) => window.grotto.frames >= n + 2, f + 3, { timeout: 60000 });
    const file = join(out, `${name}-web.png`);
    writeFileSync(file, await page.screenshot());
    const s = await page.evaluate(() => ({ rooms: window.grotto.rooms_loaded, errors: window.grotto.errors }));
    console.log(`${file}: ${s.rooms} rooms${problems.length || s.errors.length ? `, problems: ${[...problems, ...s.errors].join("; ")}` : ""}`);
    await page.close();
  }
} finally {
  await browser.close();
  for (const s of servers.values()) await s.stop();
}
