// Decoding a real room payload with Google's Draco decoder (draco3d, as the browser's worker
// does), PROTOCOL's validation, the normals rule, the rims, and the subdivision
// (web/src/decode_core.js). Fixtures: room frames fetched once from grotto-server (seed 7,
// default parameters, version 2, lod 0): 0.0.0.r0 and its neighbour 0.0.0.r34.
import { test, before } from "node:test";
import assert from "node:assert/strict";
import fs from "node:fs";
import draco3d from "draco3d";
import { parseRoomFrame } from "../src/protocol.js";
import "../src/decode_core.js";

const D = globalThis.GrottoDecode;
let M;
const frames = {};
before(async () => {
  M = await draco3d.createDecoderModule({});
  for (const id of ["0.0.0.r0", "0.0.0.r34"]) {
    const bytes = new Uint8Array(fs.readFileSync(new URL(`./fixtures/room_v2_7_${id}.bin`, import.meta.url)));
    const r = parseRoomFrame(bytes);
    assert.ok(r.ok, r.message);
    frames[id] = r.frame;
  }
});

test("a real payload decodes and passes the checks", () => {
  const f = frames["0.0.0.r0"];
  const room = D.decodeRoom(M, f.payload, f);
  assert.ok(room.vertices >= 3 && room.triangles >= 1);
  assert.equal(room.normals.length, 3 * room.vertices);
  for (let v = 0; v < room.vertices; ++v) {
    const l = Math.hypot(room.normals[3 * v], room.normals[3 * v + 1], room.normals[3 * v + 2]);
    assert.ok(Math.abs(l - 1) < 1e-5);
  }
  // Rims: one loop per portal, every k present, on the 1/256 m grid.
  assert.deepEqual(Object.keys(room.rims).sort(), ["0", "1"]);
  for (const loop of Object.values(room.rims)) {
    assert.ok(loop.length >= 3);
    for (const p of loop) {
      assert.ok(Array.isArray(p));
      for (const x of p) assert.ok(Number.isInteger(x * 256));
    }
  }
  // Subdivided: 4x the triangles, the collision mesh as sent.
  assert.equal(room.draw.indices.length, 4 * 3 * room.triangles);
  assert.equal(room.collision.indices.length, 3 * room.triangles);
  assert.ok(room.spacing > 0.05 && room.spacing < 5);
});

test("a shared portal's rim decodes to the same world positions in both rooms", () => {
  const a = frames["0.0.0.r0"], b = frames["0.0.0.r34"];
  const ra = D.decodeRoom(M, a.payload, a), rb = D.decodeRoom(M, b.payload, b);
  const sa = a.portals.findIndex((p) => p.to === b.id), sb = b.portals.findIndex((p) => p.to === a.id);
  assert.ok(sa >= 0 && sb >= 0);
  const la = ra.rims[sa], lb = rb.rims[sb];
  assert.equal(la.length, lb.length);
  for (let k = 0; k < la.length; ++k) assert.deepEqual(la[k], lb[k], `k = ${k}`);
  // ... and the same normals bit for bit (PROTOCOL: Normals, the rim rule).
  const normalAt = (room, slot, k) => {
    for (let v = 0; v < room.vertices; ++v)
      if (room.rim[2 * v] === slot + 1 && room.rim[2 * v + 1] === k) return [...room.normals.subarray(3 * v, 3 * v + 3)];
    return null;
  };
  for (let k = 0; k < la.length; ++k) assert.deepEqual(normalAt(ra, sa, k), normalAt(rb, sb, k));
});

test("the rim normal rule: level with the portal disc, pointing at its axis", () => {
  const portals = [{ centre: [10, 5, 0], normal: [0, 0, 1] }];
  const positions = new Float32Array([2, 0, 0.5, 0, 0, 0, 0, 1, 0]); // vertex 0 on the rim
  const rim = new Uint16Array([1, 0, 0, 0, 0, 0]);
  const n = D.deriveNormals(positions, new Uint32Array([0, 1, 2]), rim, [10, 5, 0], portals);
  // d = (12, 5, 0.5) - (10, 5, 0) = (2, 0, 0.5); r = (2, 0, 0); normal = -r/|r| = (-1, 0, 0).
  assert.deepEqual([...n.subarray(0, 3)], [-1, -0, -0]); // -r / |r|, signs and all
  // The others: the area-weighted face normal cross(b - a, c - a) = (0,0,0)-(2,0,.5) x (0,1,0)-(2,0,.5).
  const u = [-2, 0, -0.5], w = [-2, 1, -0.5];
  const c = [u[1] * w[2] - u[2] * w[1], u[2] * w[0] - u[0] * w[2], u[0] * w[1] - u[1] * w[0]];
  const l = Math.hypot(...c);
  assert.deepEqual([...n.subarray(3, 6)], c.map((x) => Math.fround(x / l)));
  // An isolated vertex (no triangle): (0, 1, 0).
  const n2 = D.deriveNormals(new Float32Array([0, 0, 0, 1, 0, 0, 0, 0, 1, 5, 5, 5]), new Uint32Array([0, 1, 2]), new Uint16Array(8), [0, 0, 0], []);
  assert.deepEqual([...n2.subarray(9, 12)], [0, 1, 0]);
});

test("subdivision: shared edges give one midpoint, no cracks; rims keep weight 1", () => {
  // Two triangles sharing edge 1-2; vertices 1 and 2 on a rim.
  const mesh = {
    positions: new Float32Array([0, 0, 0, 1, 0, 0, 0, 0, 1, 1, 0, 1]),
    normals: new Float32Array([0, 1, 0, 0, 1, 0, 0, 1, 0, 0, 1, 0]),
    roughness: new Float32Array([0, 1, 1, 0]),
    mineral: new Float32Array(4),
    rimWeight: new Float32Array([0, 1, 1, 0]),
    indices: new Uint32Array([0, 2, 1, 1, 2, 3]),
  };
  const s = D.subdivide(mesh, [0, 0, 0]);
  assert.equal(s.indices.length, 24);
  assert.equal(s.positions.length / 3, 4 + 5); // 5 distinct edges
  // The shared edge's midpoint is one vertex, used by both halves.
  const mids = new Map();
  for (let v = 4; v < 9; ++v) mids.set([...s.positions.subarray(3 * v, 3 * v + 3)].join(","), v);
  assert.ok(mids.has("0.5,0,0.5"));
  const m = mids.get("0.5,0,0.5");
  const useCount = [...s.indices].filter((i) => i === m).length;
  assert.equal(useCount, 6); // three sub-triangles on each side
  assert.equal(s.rimWeight[m], 1); // a rim edge keeps rim weight 1
  assert.equal(s.rimWeight[mids.get("0.5,0,0")], 0.5);
  // Every original edge split: each sub-triangle's corners are distinct.
  for (let i = 0; i < s.indices.length; i += 3) assert.equal(new Set(s.indices.subarray(i, i + 3)).size, 3);
  // Orientation kept: each sub-triangle's normal points like its parent's (+y here).
  for (let i = 0; i < s.indices.length; i += 3) {
    const [a, b, c] = [s.indices[i], s.indices[i + 1], s.indices[i + 2]].map((v) => [...s.positions.subarray(3 * v, 3 * v + 3)]);
    const u = [b[0] - a[0], b[2] - a[2]], w = [c[0] - a[0], c[2] - a[2]];
    assert.ok(u[1] * w[0] - u[0] * w[1] > 0);
  }
});

test("subdivision of a real room: both rooms of a portal make the same rim-edge midpoints", () => {
  const a = frames["0.0.0.r0"], b = frames["0.0.0.r34"];
  const ra = D.decodeRoom(M, a.payload, a), rb = D.decodeRoom(M, b.payload, b);
  const rimMids = (room, frame) => {
    const out = new Set();
    const d = room.draw;
    for (let v = room.vertices; v < d.positions.length / 3; ++v)
      if (d.rimWeight[v] === 1) out.add([0, 1, 2].map((k) => (frame.origin[k] + d.positions[3 * v + k]).toFixed(4)).join(","));
    return out;
  };
  const ma = rimMids(ra, a), mb = rimMids(rb, b);
  let shared = 0;
  for (const p of mb) if (ma.has(p)) shared++;
  assert.ok(shared >= 10, `shared rim-edge midpoints: ${shared}`);
  // No crack inside a room: every edge of the subdivided mesh is used by at most two triangles.
  const edges = new Map();
  const I = ra.draw.indices;
  for (let i = 0; i < I.length; i += 3)
    for (let e = 0; e < 3; ++e) {
      const x = I[i + e], y = I[i + ((e + 1) % 3)];
      const k = x < y ? `${x},${y}` : `${y},${x}`;
      edges.set(k, (edges.get(k) || 0) + 1);
    }
  for (const c of edges.values()) assert.ok(c <= 2);
});

test("payload validation refuses before and after Draco", () => {
  const f = frames["0.0.0.r0"];
  const bad = (mutate, re, frame = f) => {
    const p = f.payload.slice();
    mutate(p);
    assert.throws(() => D.decodeRoom(M, p, frame), (e) => e.code === "bad_frame" && re.test(e.message));
  };
  bad((p) => (p[0] = 0x41), /magic/);
  bad((p) => (p[5] = 3), /bitstream version/);
  bad((p) => (p[7] = 0), /triangle mesh/);
  bad((p) => (p[8] = 0), /edgebreaker/);
  bad((p) => (p[9] = 1), /flags/);
  // Declared counts over the limits (the vertex count varint at byte 12): 5 bytes of 0xff..
  assert.throws(() => D.checkHeader(Uint8Array.from([...f.payload.subarray(0, 12), 0x80, 0x80, 0x02, 1, 0, 1, 0]), 0), /declares 32768 vertices/);
  assert.throws(() => D.checkHeader(Uint8Array.from([...f.payload.subarray(0, 12), 3, 0xff, 0xff, 0x03, 0, 1, 0]), 0), /triangles, limit 32768/);
  assert.throws(() => D.checkHeader(Uint8Array.from([...f.payload.subarray(0, 12), 3, 1, 9, 1, 0]), 0), /attribute tables/);
  assert.throws(() => D.checkHeader(f.payload.subarray(0, 13), 0), /truncated/);
  // Over 64 KiB at lod 0.
  assert.throws(() => D.checkHeader(new Uint8Array(65537), 0), /over 65536/);
  // A rim slot not below the frame's portal count.
  assert.throws(() => D.decodeRoom(M, f.payload, { ...f, portals: f.portals.slice(0, 1) }), /rim slot 1 out of range/);
  // A version 1 session expects four attributes.
  assert.throws(() => D.decodeRoom(M, f.payload, { ...f, version: 1 }), /3 attributes, expected 4/);
  // Truncated payload: Draco fails, cleanly.
  assert.throws(() => D.decodeRoom(M, f.payload.slice(0, f.payload.length >> 1), f), (e) => e.code === "bad_frame");
});

test("validate: decoded values", () => {
  const base = () => ({
    positions: new Float32Array([0, 0, 0, 1, 0, 0, 0, 0, 1]), channels: new Float32Array([0, 0, 0.5, 0.5, 1, 1]),
    rim: new Uint16Array(6), indices: new Uint32Array([0, 2, 1]), sentNormals: null, n: 3, t: 1,
  });
  D.validate(base(), [0, 0, 0], 0);
  const bad = (mutate, re, portals = 1) => {
    const d = base();
    mutate(d);
    assert.throws(() => D.validate(d, [0, 0, 0], portals), re);
  };
  bad((d) => (d.positions[0] = NaN), /not finite/);
  bad((d) => (d.positions[4] = 1024.5), /beyond/);
  bad((d) => (d.channels[1] = 1.01), /channel/);
  bad((d) => (d.channels[2] = -0.01), /channel/);
  bad((d) => (d.rim[0] = 2), /rim slot 1 out of range/);
  bad((d) => (d.rim[1] = 3), /rim index off any rim/);
  bad((d) => { d.rim[0] = 1; d.positions[0] = 0.001; }, /1\/256 m grid/);
  bad((d) => (d.indices[1] = 3), /out of range/);
  bad((d) => (d.indices[1] = 0), /degenerate/);
});
