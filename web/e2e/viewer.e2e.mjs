// The browser viewer in a real browser: Debian's chromium, headless, with SwiftShader's
// WebGL2, driven by playwright-core, against grotto-servers this file starts (harness.mjs) on
// loopback. Run by CTest (web.e2e) with GROTTO_SERVER, GROTTO_LAYOUT and GROTTO_RIM_REFERENCE
// set; GROTTO_WEB_REPORT names a JSON file for the figures it measures (first picture, decode
// times): benchmarks' numbers, reported, never asserted against a time.
import { test, before, after, afterEach } from "node:test";
import assert from "node:assert/strict";
import { execFileSync } from "node:child_process";
import { mkdtempSync, writeFileSync, rmSync } from "node:fs";
import { tmpdir } from "node:os";
import { join } from "node:path";
import { startServer, launchBrowser, openPage, layoutRoom, readPng, pictureSpread } from "./harness.mjs";

const report = {};
let server;
let browser;
const scratch = mkdtempSync(join(tmpdir(), "grotto-web-"));

before(async () => {
  server = await startServer();
  browser = await launchBrowser();
});
after(async () => {
  if (process.env.GROTTO_WEB_REPORT) writeFileSync(process.env.GROTTO_WEB_REPORT, JSON.stringify(report, null, 2) + "\n");
  await browser?.close();
  await server?.stop();
  rmSync(scratch, { recursive: true, force: true });
});
// Every page and context a test opens is closed after it, passed or failed: a failed test's page
// would go on drawing with SwiftShader and starve the tests after it of the CPU.
const opened = [];
const open = async (url) => {
  const page = await openPage(browser, url);
  opened.push(page);
  return page;
};
afterEach(async () => {
  for (const p of opened.splice(0)) await p.close().catch(() => {});
});

const state = (page) => page.evaluate(() => {
  const g = window.grotto;
  return { rooms_loaded: g.rooms_loaded, frames: g.frames, requests: g.requests, cancels: g.cancels,
           errors: [...g.errors], decode_ms: [...g.decode_ms], subdivide_ms: [...g.subdivide_ms], status: g.status, message: g.message,
           pose: { ...g.pose }, reconnects: g.reconnects };
});
const waitFor = (page, fn, arg, timeout = 90000) => page.waitForFunction(fn, arg, { timeout, polling: 100 });
const median = (a) => { const s = [...a].sort((x, y) => x - y); return s.length ? s[s.length >> 1] : null; };

test("the page loads rooms and draws the cave, with no error", async () => {
  const t0 = Date.now();
  const page = await open(`${server.url}/`);
  await waitFor(page, () => window.grotto && window.grotto.rooms_loaded >= 1 && window.grotto.frames >= 2);
  report.first_picture_ms = Date.now() - t0;
  await waitFor(page, () => window.grotto.rooms_loaded >= 5 && window.grotto.frames >= 10);
  await page.waitForTimeout(1500);
  const png = readPng(await page.screenshot());
  const spread = pictureSpread(png);
  writeFileSync(join(scratch, "first.png"), await page.screenshot());
  const s = await state(page);
  report.decode_ms_median = median(s.decode_ms);
  report.subdivide_ms_median = median(s.subdivide_ms);
  report.rooms_loaded = s.rooms_loaded;
  report.picture = spread;
  assert.ok(spread.other > 0.3 && spread.levels > 40 && spread.colours > 200,
            `the canvas is (nearly) one colour: ${JSON.stringify(spread)}`);
  assert.equal(s.status, "open");
  assert.deepEqual(s.errors, []);
  assert.deepEqual(page.problems, [], "console errors or exceptions");
  await page.close();
});

test("walking forward asks for more rooms", async () => {
  const page = await open(`${server.url}/`);
  await waitFor(page, () => window.grotto && window.grotto.rooms_loaded >= 3 && window.grotto.frames >= 3);
  await page.waitForTimeout(1000);
  const before = await state(page);
  await page.click("canvas");
  await page.keyboard.press("g");  // fly: walls do not stop the walk this test is about
  // W held for 6 s and 10 frames at least: the walk moves by each frame's time (at most 1 s of
  // it), so a page drawing slowly on a busy machine walks in fewer, longer steps.
  await page.keyboard.down("w");
  const held = await page.evaluate(() => window.grotto.frames);
  await page.waitForTimeout(6000);
  await waitFor(page, (f) => window.grotto.frames >= f + 10, held);
  await page.keyboard.up("w");
  await page.waitForTimeout(1000);
  const later = await state(page);
  const moved = Math.hypot(later.pose.x - before.pose.x, later.pose.y - before.pose.y, later.pose.z - before.pose.z);
  assert.ok(moved > 3, `W moved the player ${moved.toFixed(2)} m`);
  assert.ok(later.requests > before.requests, `requests ${before.requests} -> ${later.requests} after walking ${moved.toFixed(1)} m`);
  assert.deepEqual(page.problems, []);
  await page.close();
});

test("a room's formations are lit by the lights its rock is lit by", async () => {
  // Seed 7's hall, lit by its glow-worms: the haze of its lights lies before its formations as
  // before its rock, and a passage's formations get the spill of the hall's lights as its rock does.
  const [x, y, z] = layoutRoom("0.0.0.r0").centre;
  const page = await open(`${server.url}/?seed=7&pose=${x},${y},${z},270,5&fly=1`);
  await waitFor(page, () => window.grotto && window.grotto.rooms_loaded >= 5 && window.grotto.lit().length >= 3);
  await page.waitForTimeout(1000);
  const lit = await page.evaluate(() => window.grotto.lit());
  assert.ok(lit.some((r) => r.rock.count > 0 && r.rock.haze_count > 0), `no lit room with formations: ${JSON.stringify(lit)}`);
  for (const r of lit) assert.deepEqual(r.formations, r.rock, `room ${r.id}: its formations' lights differ from its rock's`);
  await page.close();
});

test("a link opens its place and the page gives the link of where it is", async () => {
  const room = layoutRoom("1.0.0.r0");
  const [x, y, z] = room.centre;
  // Degrees, as grotto-client's --pose takes them; flying, so that the eye stays where the link
  // put it (the room's centre is in mid-air: walking, the player falls to the floor).
  const page = await open(`${server.url}/?seed=7&pose=${x},${y},${z},70,-10&fly=1`);
  await waitFor(page, () => window.grotto && window.grotto.rooms_loaded >= 1 && window.grotto.frames >= 2);
  const s = await state(page);
  assert.ok(Math.hypot(s.pose.x - x, s.pose.y - y, s.pose.z - z) < 2.0, `pose ${JSON.stringify(s.pose)} not at ${room.centre}`);
  assert.ok(Math.abs(s.pose.yaw - (70 * Math.PI) / 180) < 1e-6, `yaw ${s.pose.yaw} rad`);
  // The link and the pose it should name, read at once (walking, gravity moves the eye between
  // two reads).
  const { link, now } = await page.evaluate(() => ({ link: window.grotto.link(), now: window.grotto.pose }));
  const u = new URL(link);
  assert.equal(u.searchParams.get("seed"), "7");
  assert.equal(u.searchParams.get("fly"), "1", `${link}: a flying player's link flies`);
  const pose = u.searchParams.get("pose").split(",").map(Number);
  assert.equal(pose.length, 5);
  assert.ok(Math.hypot(pose[0] - now.x, pose[1] - now.y, pose[2] - now.z) < 0.01, `${link} vs ${JSON.stringify(now)}`);
  assert.ok(Math.abs(pose[3] - (now.yaw * 180) / Math.PI) < 0.01, `${link}: yaw in degrees`);
  await page.close();
});

test("a portal's rim decodes to the native decoder's positions, bit for bit", async () => {
  const page = await open(`${server.url}/`);
  await waitFor(page, () => window.grotto && window.grotto.rooms_loaded >= 3);
  const ids = await page.evaluate(() => window.grotto.rooms());
  const version = await (await fetch(`${server.url}/version`)).json();
  let compared = 0;
  for (const id of ids.slice(0, 3)) {
    const bytes = Buffer.from(await (await fetch(`${server.url}/rooms/v2/7/${version.params}/0/${id}`)).arrayBuffer());
    const file = join(scratch, `${id}.frame`);
    writeFileSync(file, bytes);
    const native = JSON.parse(execFileSync(process.env.GROTTO_RIM_REFERENCE, [file]).toString());
    for (let slot = 0; slot < native.rims.length; slot++) {
      const browserRim = await page.evaluate(([i, s]) => window.grotto.rim(i, s), [id, slot]);
      assert.equal(browserRim.length, native.rims[slot].length, `${id} portal ${slot}: loop length`);
      for (let k = 0; k < browserRim.length; k++) {
        for (let a = 0; a < 3; a++) {
          // Object.is: the same double, bit for bit (and -0 apart from 0).
          assert.ok(Object.is(browserRim[k][a], native.rims[slot][k][a]),
                    `${id} portal ${slot} vertex ${k}: ${browserRim[k]} vs native ${native.rims[slot][k]}`);
        }
        compared++;
      }
    }
  }
  assert.ok(compared > 20, `only ${compared} rim vertices compared`);
  report.rim_vertices_compared = compared;
  await page.close();
});

test("hostile frames and a closed socket give a clear message, then a reconnect", async () => {
  const context = await browser.newContext({ viewport: { width: 640, height: 360 } });
  opened.push(context);
  const page = await context.newPage();
  page.problems = [];
  let route;
  await page.routeWebSocket(/\/ws/, (ws) => {
    route = ws;
    const upstream = ws.connectToServer();
    ws.onMessage((m) => upstream.send(m));
    upstream.onMessage((m) => ws.send(m));
  });
  await page.goto(`${server.url}/`);
  await waitFor(page, () => window.grotto && window.grotto.rooms_loaded >= 1);
  // A room frame with the wrong magic, one that lies about its size, and a text frame that is not
  // JSON: each refused and counted, nothing used, the page goes on.
  const bad = Buffer.alloc(120);
  bad.write("NOPE", 0, "ascii");
  route.send(bad);
  const lying = Buffer.alloc(80);
  lying.write("GRTO", 0, "ascii");
  lying.writeUInt16LE(2, 4); lying[6] = 1; lying.writeUInt32LE(1000, 20);
  route.send(lying);
  route.send("{not json");
  await waitFor(page, () => window.grotto.errors.length >= 3, undefined, 20000);
  let s = await state(page);
  assert.match(s.errors.join("\n"), /bad_frame/);
  assert.ok(s.message.length > 0, "no message on screen");
  const shown = await page.textContent("#message");
  assert.ok(shown && shown.length > 0, "#message is empty");
  // The server goes away: the page says so and connects again.
  const reconnects = s.reconnects;
  route.close({ code: 1011, reason: "test" });
  await waitFor(page, (r) => window.grotto.reconnects > r && window.grotto.status === "open", reconnects, 30000);
  s = await state(page);
  assert.equal(s.status, "open");
  await context.close();
});

test("turning back cancels the rooms ahead that are still on their way", async () => {
  // The slowest link a server allows (1 kbit/s): the first room goes out at once (the bandwidth
  // bucket is full at welcome and one frame may overdraw it), the rooms asked for next wait at
  // the server for many seconds, in flight, whatever the machine's load. At 16 kbit/s they could
  // all arrive between the wait below and the jump (a fresh-clone run failed so).
  const slow = await startServer(["--max-kbps", "1"]);
  try {
    const page = await open(`${slow.url}/`);
    await waitFor(page, () => window.grotto && window.grotto.rooms_loaded >= 1 && window.grotto.in_flight >= 3);
    const before = await state(page);
    assert.ok(before.rooms_loaded <= 2, `rooms arrived faster than 1 kbit/s allows: ${before.rooms_loaded}`);
    const far = layoutRoom("3.0.0.r0");
    await page.evaluate(([x, y, z]) => window.grotto.setPose(x, y, z, 0, 0), far.centre);
    // Cancels round the old place, requests round the new one (after its locate: a moment later).
    try {
      await waitFor(page, ([c, r]) => window.grotto.cancels > c && window.grotto.requests > r,
                    [before.cancels, before.requests], 30000);
    } catch (e) {
      const s = await state(page);
      throw new Error(`${e.message}: before the jump ${JSON.stringify({ ...before, decode_ms: undefined, subdivide_ms: undefined })}, ` +
                      `now ${JSON.stringify({ ...s, decode_ms: undefined, subdivide_ms: undefined })}, room ${await page.evaluate(() => window.grotto.room)}`);
    }
    const later = await state(page);
    assert.ok(later.cancels > before.cancels);
    assert.ok(later.requests > before.requests, "nothing asked for round the new place");
    assert.equal(await page.evaluate(() => window.grotto.room), "3.0.0.r0");
    await page.close();
  } finally {
    await slow.stop();
  }
});

test("--no-viewer serves no page; the viewer's files carry types and ETags", async () => {
  const index = await fetch(`${server.url}/`);
  assert.equal(index.status, 200);
  assert.match(index.headers.get("content-type"), /^text\/html/);
  const tag = index.headers.get("etag");
  assert.match(tag, /^"[0-9a-f]{16}"$/);
  assert.equal((await fetch(`${server.url}/`, { headers: { "If-None-Match": tag } })).status, 304);
  const wasm = await fetch(`${server.url}/viewer/lib/draco_decoder.wasm`);
  assert.equal(wasm.headers.get("content-type"), "application/wasm");
  const version = await (await fetch(`${server.url}/version`)).json();
  const extras = await fetch(`${server.url}/extras/v2/7/${version.params}/0/0.0.0.r0`);
  assert.equal(extras.status, 200);
  const body = await extras.json();
  assert.equal(body.room, "0.0.0.r0");
  assert.equal(body.formations.data.length, 16 * body.formations.count);
  assert.equal((await fetch(`${server.url}/extras/v2/7/${version.params}/0/0.0.0.r4095`)).status, 404);
  assert.equal((await fetch(`${server.url}/extras/v2/7/0000000000000000/0/0.0.0.r0`)).status, 404);
  const off = await startServer(["--no-viewer"]);
  try {
    assert.equal((await fetch(`${off.url}/`)).status, 404);
    assert.equal((await fetch(`${off.url}/extras/v2/7/${version.params}/0/0.0.0.r0`)).status, 404);
    assert.equal((await fetch(`${off.url}/healthz`)).status, 200);
  } finally {
    await off.stop();
  }
});
