// A development server for the viewer: serves web/ in the layout grotto-server serves it (/ the
// page, /viewer/<name>.js web/src, /viewer/shaders.js generated, /viewer/lib/ three.js and the
// Draco decoder) straight from the sources, and passes everything else (/ws, /version, /rooms/...,
// /extras/...) to a running grotto-server. For working on the viewer without rebuilding the server:
//   node web/tools/dev_server.mjs --port 8080 --backend 127.0.0.1:7878 [--mock-extras]
// --mock-extras answers /extras/... itself when the backend has no such resource (404): no lights
// and no formations, or with --mock-extras=demo one light and one stalagmite at each room's centre
// (made-up places: only to exercise the shaders).
import http from "node:http";
import net from "node:net";
import fs from "node:fs";
import path from "node:path";
import { fileURLToPath } from "node:url";
import { generateShadersModule } from "./shaders.mjs";

const web = path.resolve(path.dirname(fileURLToPath(import.meta.url)), "..");
const args = process.argv.slice(2);
const arg = (name, dflt) => {
  const a = args.find((x) => x === `--${name}` || x.startsWith(`--${name}=`));
  if (!a) return dflt;
  const eq = a.indexOf("=");
  if (eq >= 0) return a.slice(eq + 1);
  const i = args.indexOf(a);
  return args[i + 1] && !args[i + 1].startsWith("--") ? args[i + 1] : true;
};
const port = Number(arg("port", 8080));
const [bhost, bport] = String(arg("backend", "127.0.0.1:7878")).split(":");
const mock = arg("mock-extras", false);

const types = { ".html": "text/html; charset=utf-8", ".js": "text/javascript; charset=utf-8", ".wasm": "application/wasm" };
function file(p) {
  if (p === "/" || p === "/index.html") return path.join(web, "index.html");
  const lib = {
    "/viewer/lib/three.module.js": "node_modules/three/build/three.module.js",
    "/viewer/lib/three.core.js": "node_modules/three/build/three.core.js",
    "/viewer/lib/draco_decoder.js": "node_modules/draco3d/draco_decoder_nodejs.js",
    "/viewer/lib/draco_decoder.wasm": "node_modules/draco3d/draco_decoder.wasm",
  }[p];
  if (lib) return path.join(web, lib);
  const m = /^\/viewer\/([a-z_0-9]+\.js)$/.exec(p);
  if (m && m[1] !== "shaders.js") return path.join(web, "src", m[1]);
  return null;
}

function proxy(req, res, onStatus) {
  const up = http.request({ host: bhost, port: bport, path: req.url, method: req.method, headers: req.headers }, (r) => {
    if (onStatus && onStatus(r)) return;
    res.writeHead(r.statusCode, r.headers);
    r.pipe(res);
  });
  up.on("error", (e) => {
    res.writeHead(502, { "content-type": "text/plain" });
    res.end(`backend: ${e.message}\n`);
  });
  req.pipe(up);
}

const server = http.createServer((req, res) => {
  const url = new URL(req.url, "http://x");
  if (url.pathname === "/viewer/shaders.js") {
    res.writeHead(200, { "content-type": types[".js"], "cache-control": "no-store" });
    res.end(generateShadersModule(path.resolve(web, "../shaders")));
    return;
  }
  const f = file(url.pathname);
  if (f) {
    fs.readFile(f, (err, data) => {
      if (err) {
        res.writeHead(404);
        res.end();
        return;
      }
      res.writeHead(200, { "content-type": types[path.extname(f)] || "application/octet-stream", "cache-control": "no-store" });
      res.end(data);
    });
    return;
  }
  if (mock && url.pathname.startsWith("/extras/")) {
    proxy(req, res, (r) => {
      if (r.statusCode !== 404) return false;
      r.resume();
      const id = url.pathname.split("/").pop();
      mockExtras(url.pathname, id).then((body) => {
        res.writeHead(200, { "content-type": "application/json" });
        res.end(JSON.stringify(body));
      });
      return true;
    });
    return;
  }
  proxy(req, res);
});

async function mockExtras(p, id) {
  const [, , v, seed, params, lod] = p.split("/");
  const body = { room: id, origin: [0, 0, 0], lights: [], formations: { count: 0, data: [] } };
  if (mock !== "demo") return body;
  // Fetch the room's frame for its origin and centre.
  const frame = await new Promise((resolve) => {
    http.get({ host: bhost, port: bport, path: `/rooms/${v}/${seed}/${params}/${lod}/${id}` }, (r) => {
      const chunks = [];
      r.on("data", (c) => chunks.push(c));
      r.on("end", () => resolve(Buffer.concat(chunks)));
    }).on("error", () => resolve(null));
  });
  if (!frame || frame.length < 80) return body;
  const origin = [24, 32, 40].map((o) => frame.readDoubleLE(o));
  const centre = [48, 56, 64].map((o) => frame.readDoubleLE(o));
  const radius = frame.readDoubleLE(72);
  body.origin = origin;
  body.lights.push({ kind: "crystals", position: centre, colour: [0.4, 1.2, 1.0], range: 12, size: 1.5, source_radius: 0.8, glow: 2, seed: 0.42, bound_centre: centre, bound_radius: radius * 1.1 });
  const root = [centre[0] - origin[0], centre[1] - origin[1] - 2, centre[2] - origin[2]];
  body.formations = { count: 1, data: [...root, 1.2, 0.15, 0.02, 0.3, 1, 3, 0.3, 0.05, 0.1, 0.3, 0.5, 0, 0] };
  return body;
}

server.on("upgrade", (req, socket, head) => {
  const up = net.connect(Number(bport), bhost, () => {
    let raw = `${req.method} ${req.url} HTTP/1.1\r\n`;
    for (let i = 0; i < req.rawHeaders.length; i += 2) raw += `${req.rawHeaders[i]}: ${req.rawHeaders[i + 1]}\r\n`;
    up.write(raw + "\r\n");
    if (head && head.length) up.write(head);
    up.pipe(socket);
    socket.pipe(up);
  });
  up.on("error", () => socket.destroy());
  socket.on("error", () => up.destroy());
});

server.listen(port, "127.0.0.1", () => console.log(`viewer on http://127.0.0.1:${port}/ (backend ${bhost}:${bport})`));
