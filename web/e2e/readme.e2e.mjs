// The README's first screen (everything above its first "## " heading), tried as a new user
// would: a grotto-server started as written (no flags: its default port and world), every link
// the screen gives opened in Debian's chromium, and every other program line it shows run as
// written, build/bin/ being the suite's build. Run by CTest (web.readme) with GROTTO_SERVER set.
import { test, before, after } from "node:test";
import assert from "node:assert/strict";
import { spawnSync } from "node:child_process";
import { mkdtempSync, readFileSync, rmSync, statSync } from "node:fs";
import { tmpdir } from "node:os";
import { dirname, join } from "node:path";
import { fileURLToPath } from "node:url";
import { startServer, launchBrowser, openPage } from "./harness.mjs";

const root = join(dirname(fileURLToPath(import.meta.url)), "..", "..");
const readme = readFileSync(join(root, "README.md"), "utf8");
const firstScreen = readme.split(/^## /m)[0];
const bin = dirname(process.env.GROTTO_SERVER || "");

// The links of the first screen: absolute ones on the README's server, and paths (`/?seed=...`)
// that the text says to open on it.
const origin = (firstScreen.match(/http:\/\/127\.0\.0\.1:\d+/) || [])[0];
const links = [...new Set([
  ...(firstScreen.match(/http:\/\/127\.0\.0\.1:\d+\/[^\s`)>\]]*/g) || []),
  ...[...firstScreen.matchAll(/`(\/\?[^`\s]+)`/g)].map((m) => origin + m[1]),
])];
// The program lines of the first screen: each `build/bin/...` step of its code, as written.
const commands = [...new Set(
  [...firstScreen.matchAll(/```[a-z]*\n([\s\S]*?)```|`([^`]+)`/g)]
    // A code block's lines; an inline span wrapped over lines is one line.
    .flatMap((m) => (m[1] ?? m[2].replace(/\s+/g, " ")).split(/\n|&&/))
    .map((c) => c.replace(/#.*$/, "").trim())
    .filter((c) => c.startsWith("build/bin/")),
)];

let server;
let browser;
const scratch = mkdtempSync(join(tmpdir(), "grotto-readme-"));
before(async () => {
  assert.ok(origin, "the README's first screen names no http://127.0.0.1:PORT/ link");
  assert.ok(commands.includes("build/bin/grotto-server"),
    `the first screen does not start the server as build/bin/grotto-server: ${commands.join(" | ")}`);
  server = await startServer([], { asWritten: true });
  assert.equal(server.url, origin, "the server as written listens where the README's links point");
  browser = await launchBrowser();
});
after(async () => {
  await browser?.close();
  await server?.stop();
  rmSync(scratch, { recursive: true, force: true });
});

test("the first screen gives links and program lines to try", () => {
  assert.ok(links.length >= 2, `links: ${links.join(" ")}`);
  assert.ok(links.some((l) => /[?&]seed=(?!7\b)\d+/.test(l)), `no link to another world: ${links.join(" ")}`);
  assert.ok(commands.length >= 2, `program lines: ${commands.join(" | ")}`);
});

for (const link of links) {
  test(`the link ${link} loads rooms on a default server`, async () => {
    const page = await openPage(browser, link);
    try {
      await page.waitForFunction(
        () => window.grotto && (window.grotto.status === "stopped" ||
                                (window.grotto.rooms_loaded >= 3 && window.grotto.frames >= 3)),
        null, { timeout: 120000, polling: 200 });
      const s = await page.evaluate(() => ({ status: window.grotto.status, message: window.grotto.message,
                                              seed: window.grotto.seed, errors: [...window.grotto.errors] }));
      assert.notEqual(s.status, "stopped", `${link}: ${s.message}`);
      const asked = new URL(link).searchParams.get("seed");
      if (asked) assert.equal(String(s.seed), asked, `${link} shows another world`);
      assert.deepEqual(page.problems, []);
    } finally {
      await page.close();
    }
  });
}

// The other program lines, run as written in a scratch folder. A window needs a display: without
// one, the README says the client says so, and that is what it must do.
for (const command of commands.filter((c) => c !== "build/bin/grotto-server")) {
  test(`${command} does what the README says`, { timeout: 600000 }, () => {
    const [program, ...args] = command.split(/\s+/);
    const env = { ...process.env };
    delete env.DISPLAY;
    delete env.WAYLAND_DISPLAY;
    const r = spawnSync(join(bin, program.slice("build/bin/".length)), args,
                        { cwd: scratch, env, encoding: "utf8", timeout: 540000 });
    const wantsWindow = !/--(screenshot|bench|help|version)\b/.test(command);
    if (wantsWindow) {
      assert.notEqual(r.status, 0, `${command} ran without a display: ${r.stdout}`);
      assert.match(r.stderr, /display/i, `${command} did not say that it needs a display: ${r.stderr}`);
    } else {
      assert.equal(r.status, 0, `${command}: exit ${r.status} ${r.signal || ""}: ${r.stderr}`);
      for (const f of args.filter((a) => /\.(png|json)$/.test(a))) {
        assert.ok(statSync(join(scratch, f)).size > 1000, `${command} wrote no ${f}`);
      }
    }
  });
}
