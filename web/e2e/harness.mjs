// What the browser tests share: a grotto-server of their own on an ephemeral loopback port, stopped
// with its process group whatever happens; Debian's chromium, headless with SwiftShader's WebGL2,
// launched by playwright-core (no browser download); a PNG reader for screenshots.
import { spawn, execFileSync } from "node:child_process";
import { inflateSync } from "node:zlib";
import { chromium } from "playwright-core";

const started = new Set();
function stopAll() {
  for (const child of started) {
    try { process.kill(-child.pid, "SIGKILL"); } catch {}
  }
  started.clear();
}
process.on("exit", stopAll);
for (const signal of ["SIGINT", "SIGTERM", "SIGHUP"]) {
  process.on(signal, () => { stopAll(); process.exit(128 + 1); });
}

// Starts grotto-server with `args` on 127.0.0.1, port 0, and resolves with {url, stop()} once it
// answers /healthz. Its own process group, so stop() (TERM, then KILL after 10 s) takes every
// child with it. asWritten: `args` alone, the server's own defaults for the rest (its port too).
export async function startServer(args = [], { asWritten = false } = {}) {
  const bin = process.env.GROTTO_SERVER;
  if (!bin) throw new Error("GROTTO_SERVER (the grotto-server binary) is not set");
  const child = spawn(bin, asWritten ? args : ["--port", "0", "--log-level", "warn", ...args], {
    detached: true, stdio: ["ignore", "pipe", "pipe"],
  });
  started.add(child);
  let stderr = "";
  child.stderr.on("data", (d) => { stderr += d; });
  const url = await new Promise((resolve, reject) => {
    let out = "";
    const timer = setTimeout(() => reject(new Error(`grotto-server did not start in 60 s: ${stderr}`)), 60000);
    child.stdout.on("data", (d) => {
      out += d;
      const m = out.match(/listening on (http:\/\/[0-9.:]+)/);
      if (m) { clearTimeout(timer); resolve(m[1]); }
    });
    child.on("exit", (code) => { clearTimeout(timer); reject(new Error(`grotto-server exited ${code}: ${stderr}`)); });
  });
  for (let i = 0; i < 200; i++) {
    try { if ((await fetch(`${url}/healthz`)).ok) break; } catch {}
    await new Promise((r) => setTimeout(r, 100));
  }
  const stop = async () => {
    if (!started.has(child)) return;
    started.delete(child);
    if (child.exitCode !== null) return;
    const gone = new Promise((r) => child.once("exit", r));
    try { process.kill(-child.pid, "SIGTERM"); } catch {}
    const timer = setTimeout(() => { try { process.kill(-child.pid, "SIGKILL"); } catch {} }, 10000);
    await gone;
    clearTimeout(timer);
  };
  return { url, stop, stderr: () => stderr };
}

export async function launchBrowser() {
  return chromium.launch({
    executablePath: process.env.CHROMIUM || "/usr/bin/chromium",
    args: ["--no-sandbox", "--use-angle=swiftshader", "--enable-unsafe-swiftshader",
           "--ignore-gpu-blocklist", "--disable-background-networking", "--disable-component-update",
           "--disable-sync", "--no-first-run", "--disable-quic"],
  });
}

// A page that records console errors and uncaught exceptions in page.problems.
export async function openPage(browser, url, { width = 960, height = 540 } = {}) {
  const page = await browser.newPage({ viewport: { width, height } });
  page.problems = [];
  page.on("console", (m) => { if (m.type() === "error") page.problems.push(`console: ${m.text()}`); });
  page.on("pageerror", (e) => page.problems.push(`exception: ${e.message}`));
  await page.goto(url, { waitUntil: "domcontentloaded", timeout: 60000 });
  return page;
}

// The layout's own description of a room (grotto-layout --room), for places to go.
export function layoutRoom(id, seed = 7) {
  return JSON.parse(execFileSync(process.env.GROTTO_LAYOUT, ["--seed", String(seed), "--room", id]).toString());
}

// An 8-bit RGB or RGBA, non-interlaced PNG (what chromium's screenshots are) to
// {width, height, channels, pixels}.
export function readPng(buffer) {
  let p = 8;
  let width = 0, height = 0, depth = 0, type = 0;
  const idat = [];
  while (p < buffer.length) {
    const len = buffer.readUInt32BE(p);
    const kind = buffer.toString("ascii", p + 4, p + 8);
    const data = buffer.subarray(p + 8, p + 8 + len);
    if (kind === "IHDR") {
      width = data.readUInt32BE(0); height = data.readUInt32BE(4); depth = data[8]; type = data[9];
      if (data[12] !== 0) throw new Error("interlaced PNG");
    } else if (kind === "IDAT") idat.push(data);
    p += 12 + len;
  }
  if (depth !== 8 || (type !== 2 && type !== 6)) throw new Error(`PNG type ${type} depth ${depth}`);
  const channels = type === 6 ? 4 : 3;
  const raw = inflateSync(Buffer.concat(idat));
  const stride = width * channels;
  const pixels = Buffer.alloc(height * stride);
  for (let y = 0; y < height; y++) {
    const filter = raw[y * (stride + 1)];
    const line = raw.subarray(y * (stride + 1) + 1, (y + 1) * (stride + 1));
    for (let x = 0; x < stride; x++) {
      const a = x >= channels ? pixels[y * stride + x - channels] : 0;
      const b = y > 0 ? pixels[(y - 1) * stride + x] : 0;
      const c = x >= channels && y > 0 ? pixels[(y - 1) * stride + x - channels] : 0;
      let v = line[x];
      if (filter === 1) v += a;
      else if (filter === 2) v += b;
      else if (filter === 3) v += (a + b) >> 1;
      else if (filter === 4) {
        const pa = Math.abs(b - c), pb = Math.abs(a - c), pc = Math.abs(a + b - 2 * c);
        v += pa <= pb && pa <= pc ? a : pb <= pc ? b : c;
      }
      pixels[y * stride + x] = v & 255;
    }
  }
  return { width, height, channels, pixels };
}

// How much of a picture is not its most common colour, and how many grey levels it spans.
export function pictureSpread(png) {
  const counts = new Map();
  let lo = 255, hi = 0;
  const n = png.width * png.height;
  for (let i = 0; i < n; i++) {
    const o = i * png.channels;
    const r = png.pixels[o], g = png.pixels[o + 1], b = png.pixels[o + 2];
    const key = (r << 16) | (g << 8) | b;
    counts.set(key, (counts.get(key) || 0) + 1);
    const l = (r * 3 + g * 6 + b) / 10;
    lo = Math.min(lo, l); hi = Math.max(hi, l);
  }
  const top = Math.max(...counts.values());
  return { colours: counts.size, other: 1 - top / n, levels: hi - lo };
}
