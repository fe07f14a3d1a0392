// The browser viewer's figures, as a benchmark with a JSON report, never a
// timed test: the first picture after opening the page (median of `loads` fresh pages), the decode
// and subdivision medians, and the page's memory over a walk across the world (flying forward,
// and every 10 s on to the next sector, for `minutes`), sampled every 10 s.
//   GROTTO_SERVER=build/bin/grotto-server GROTTO_LAYOUT=build/bin/grotto-layout \
//     node web/e2e/bench.mjs [--minutes 5] [--loads 3] [--json FILE]
import { writeFileSync, readFileSync } from "node:fs";
import { cpus, loadavg } from "node:os";
import { startServer, launchBrowser } from "./harness.mjs";

const arg = (name, value) => {
  const i = process.argv.indexOf(`--${name}`);
  return i > 0 ? process.argv[i + 1] : value;
};
const minutes = Number(arg("minutes", 5));
const loads = Number(arg("loads", 3));
const json = arg("json", null);
const median = (a) => { const s = [...a].sort((x, y) => x - y); return s.length ? s[s.length >> 1] : null; };

const cpuFlags = (() => {
  try {
    const f = readFileSync("/proc/cpuinfo", "utf8").match(/^flags\s*:(.*)$/m)[1].split(/\s+/);
    return ["avx2", "avx512f"].filter((x) => f.includes(x));
  } catch { return []; }
})();
const report = { cpu: cpus()[0]?.model, cores: cpus().length, cpu_flags: cpuFlags, loadavg_start: loadavg(), minutes };
const server = await startServer();
const browser = await launchBrowser();
try {
  const firsts = [];
  for (let i = 0; i < loads; i++) {
    const page = await browser.newPage({ viewport: { width: 1280, height: 720 } });
    const t0 = Date.now();
    await page.goto(`${server.url}/`);
    await page.waitForFunction(() => window.grotto && window.grotto.rooms_loaded >= 1 && window.grotto.frames >= 2, null, { timeout: 60000, polling: 20 });
    firsts.push(Date.now() - t0);
    await page.close();
  }
  report.first_picture_ms = { median: median(firsts), all: firsts };

  const page = await browser.newPage({ viewport: { width: 1280, height: 720 } });
  await page.goto(`${server.url}/`);
  await page.waitForFunction(() => window.grotto && window.grotto.rooms_loaded >= 3, null, { timeout: 60000 });
  await page.click("canvas");
  await page.keyboard.press("g");
  await page.keyboard.down("w");
  // Every 10 s the walk jumps to the next sector along +x (its first room's centre, from the
  // layout), so the page keeps meeting new rooms and its store (400 rooms) has to let old ones go.
  const { execFileSync } = await import("node:child_process");
  const centre = (k) => JSON.parse(execFileSync(process.env.GROTTO_LAYOUT, ["--seed", "7", "--room", `${k}.0.0.r0`]).toString()).centre;
  const cdp = await page.context().newCDPSession(page);
  await cdp.send("Performance.enable");
  const samples = [];
  const end = Date.now() + minutes * 60000;
  let turn = 0;
  while (Date.now() < end) {
    await page.waitForTimeout(10000);
    await page.evaluate(([c, t]) => window.grotto.setPose(c[0], c[1], c[2], t * 0.7, 0), [centre(++turn), turn]);
    const s = await page.evaluate(() => ({
      heap_mb: performance.memory ? performance.memory.usedJSHeapSize / 1048576 : null,
      rooms: window.grotto.rooms_loaded, requests: window.grotto.requests, cancels: window.grotto.cancels,
      frames: window.grotto.frames, errors: window.grotto.errors.length, last_error: window.grotto.errors.at(-1),
    }));
    // The page's JavaScript heap, and the workers' and GPU buffers are not in it: the page
    // process's resident memory says the rest (Chrome's own figure, through the DevTools protocol).
    const { metrics } = await cdp.send("Performance.getMetrics");
    const metric = (name) => metrics.find((m) => m.name === name)?.value;
    s.js_heap_mb = metric("JSHeapUsedSize") / 1048576;
    s.nodes = metric("Nodes");
    samples.push({ t_s: samples.length * 10 + 10, ...s });
    console.log(JSON.stringify(samples.at(-1)));
  }
  await page.keyboard.up("w");
  const st = await page.evaluate(() => ({ d: [...window.grotto.decode_ms], s: [...window.grotto.subdivide_ms] }));
  report.decode_ms_median = median(st.d);
  report.subdivide_ms_median = median(st.s);
  report.walk = samples;
  report.loadavg_end = loadavg();
} finally {
  await browser.close();
  await server.stop();
}
console.log(JSON.stringify({ ...report, walk: `${report.walk?.length} samples` }, null, 2));
if (json) writeFileSync(json, JSON.stringify(report, null, 2) + "\n");
