// Grotto protocol (proto/PROTOCOL.md, version 2), written from the document: room ids, the binary
// room frame's header and descriptor with its checks in the document's order, the client's
// messages and checks of the server's. Pure functions, no DOM: node's test runner imports this
// file as it is (web/test/protocol.test.mjs).

export const PROTOCOL_VERSION = 2;
export const VERSIONS_SPOKEN = [2];
export const CLIENT_NAME = "grotto-viewer 0.3.0";
export const MAX_PORTALS = 16;
export const HEADER_BYTES = 80;
export const PORTAL_BYTES = 64;
export const MAGIC = 0x4f545247; // "GRTO" read little-endian

// ---- Room ids ----

const SECTOR_LIMIT = 65535;
const GATE_BASE = 4096;
const SLOT_LIMIT = 4144; // slots >= this are invalid
const KINDS = ["x", "y", "z"];
const INT_RE = /^(0|-?[1-9][0-9]*)$/;

function parseIntField(text) {
  if (!INT_RE.test(text)) return null;
  if (text.length > 7) return null; // beyond 65535 in magnitude anyway (and no overflow)
  return Number(text);
}

// Text form to {sx, sy, sz, kind, n} or null. Throws nothing.
export function parseRoomId(text) {
  if (typeof text !== "string" || text.length === 0 || text.length > 64) return null;
  const parts = text.split(".");
  if (parts.length !== 4) return null;
  const s = parts.slice(0, 3).map(parseIntField);
  if (s.some((v) => v === null || v < -SECTOR_LIMIT || v > SECTOR_LIMIT)) return null;
  const last = parts[3];
  const kind = last.charAt(0);
  if (kind !== "r" && kind !== "x" && kind !== "y" && kind !== "z") return null;
  const rest = last.slice(1);
  if (!/^(0|[1-9][0-9]*)$/.test(rest) || rest.length > 5) return null;
  const n = Number(rest);
  if (kind === "r" ? n > 4095 : n > 15) return null;
  return { sx: s[0], sy: s[1], sz: s[2], kind, n };
}

export function isRoomId(text) {
  return parseRoomId(text) !== null;
}

export function isGateId(text) {
  const p = parseRoomId(text);
  return p !== null && p.kind !== "r";
}

// Text form to the binary form (a BigInt), or null when malformed.
export function roomIdToBinary(text) {
  const p = parseRoomId(text);
  if (p === null) return null;
  const slot = p.kind === "r" ? p.n : GATE_BASE + 16 * KINDS.indexOf(p.kind) + p.n;
  return (
    BigInt(slot) |
    (BigInt(p.sx + SECTOR_LIMIT) << 13n) |
    (BigInt(p.sy + SECTOR_LIMIT) << 30n) |
    (BigInt(p.sz + SECTOR_LIMIT) << 47n)
  );
}

// Binary form (BigInt or a number below 2^53) to the text form, or null when invalid.
export function roomIdFromBinary(value) {
  let v;
  try {
    v = BigInt(value);
  } catch {
    return null;
  }
  if (v < 0n || v >= 1n << 64n) return null;
  const slot = Number(v & 0x1fffn);
  const fx = Number((v >> 13n) & 0x1ffffn);
  const fy = Number((v >> 30n) & 0x1ffffn);
  const fz = Number((v >> 47n) & 0x1ffffn);
  if (slot >= SLOT_LIMIT) return null;
  if (fx > 2 * SECTOR_LIMIT || fy > 2 * SECTOR_LIMIT || fz > 2 * SECTOR_LIMIT) return null;
  const sx = fx - SECTOR_LIMIT, sy = fy - SECTOR_LIMIT, sz = fz - SECTOR_LIMIT;
  let tail;
  if (slot < GATE_BASE) tail = "r" + slot;
  else tail = KINDS[Math.floor((slot - GATE_BASE) / 16)] + ((slot - GATE_BASE) % 16);
  return `${sx}.${sy}.${sz}.${tail}`;
}

// ---- The binary room frame ----

function fail(code, message) {
  return { ok: false, code, message };
}

function finite3(a) {
  return Number.isFinite(a[0]) && Number.isFinite(a[1]) && Number.isFinite(a[2]);
}

function onGrid256(x) {
  return Number.isInteger(x * 256);
}

// Parses and checks a room frame (an ArrayBuffer, or a Uint8Array view) in PROTOCOL's order:
// size (too_large), magic (bad_frame), version (unsupported_version; a spoken version the session
// did not choose: bad_frame), frame type (unknown_type), header present / n <= 16 / exact size /
// reserved (bad_frame), the ids (invalid_room_id), flags and every other rule (bad_frame).
// opts: {maxFrameBytes, version (the session's), maxLod}. Returns {ok: true, frame} or
// {ok: false, code, message}. The frame: {id, idBinary, gate, lod, version, origin, centre, radius,
// portals: [{to, centre, normal, radius}], payload (Uint8Array view of the input)}.
export function parseRoomFrame(input, opts = {}) {
  const maxFrameBytes = opts.maxFrameBytes ?? 4194304;
  const sessionVersion = opts.version ?? PROTOCOL_VERSION;
  const maxLod = opts.maxLod ?? 0;
  let bytes;
  if (input instanceof ArrayBuffer) bytes = new Uint8Array(input);
  else if (ArrayBuffer.isView(input)) bytes = new Uint8Array(input.buffer, input.byteOffset, input.byteLength);
  else return fail("bad_frame", "room frame: not binary data");
  const size = bytes.byteLength;
  if (size > maxFrameBytes) return fail("too_large", `room frame: ${size} bytes, over max_frame_bytes ${maxFrameBytes}`);
  const v = new DataView(bytes.buffer, bytes.byteOffset, bytes.byteLength);
  if (size < 4 || v.getUint32(0, true) !== MAGIC) return fail("bad_frame", "room frame: wrong magic (expected GRTO)");
  if (size < 6) return fail("bad_frame", `room frame: truncated header (${size} bytes)`);
  const version = v.getUint16(4, true);
  if (version !== 1 && version !== 2) return fail("unsupported_version", `room frame: version ${version}, this viewer speaks 1 and 2`);
  if (version !== sessionVersion) return fail("bad_frame", `room frame: version ${version}, but the session chose ${sessionVersion}`);
  if (size < 7) return fail("bad_frame", `room frame: truncated header (${size} bytes)`);
  const type = v.getUint8(6);
  if (type !== 1) return fail("unknown_type", `room frame: frame type ${type}, expected 1 (room)`);
  if (size < HEADER_BYTES) return fail("bad_frame", `room frame: ${size} bytes, shorter than the 80-byte header`);
  const n = v.getUint8(17);
  if (n > MAX_PORTALS) return fail("bad_frame", `room frame: ${n} portals, over 16`);
  const L = v.getUint32(20, true);
  const expected = HEADER_BYTES + PORTAL_BYTES * n + L;
  if (size !== expected) return fail("bad_frame", `room frame: ${size} bytes, expected 80 + 64*${n} + ${L} = ${expected}`);
  if (v.getUint16(18, true) !== 0) return fail("bad_frame", "room frame: reserved bytes are not zero");
  // ids
  const idBinary = v.getBigUint64(8, true);
  const id = roomIdFromBinary(idBinary);
  if (id === null) return fail("invalid_room_id", `room frame: invalid room id 0x${idBinary.toString(16)}`);
  const portals = [];
  for (let i = 0; i < n; ++i) {
    const at = HEADER_BYTES + PORTAL_BYTES * i;
    const toBinary = v.getBigUint64(at, true);
    const to = roomIdFromBinary(toBinary);
    if (to === null) return fail("invalid_room_id", `room frame ${id}: portal ${i}: invalid room id 0x${toBinary.toString(16)}`);
    portals.push({
      to,
      centre: [v.getFloat64(at + 8, true), v.getFloat64(at + 16, true), v.getFloat64(at + 24, true)],
      normal: [v.getFloat64(at + 32, true), v.getFloat64(at + 40, true), v.getFloat64(at + 48, true)],
      radius: v.getFloat64(at + 56, true),
    });
  }
  // flags and the rest
  const flags = v.getUint8(7);
  if ((flags & 0xfe) !== 0) return fail("bad_frame", `room frame ${id}: flag bits 1-7 set (0x${flags.toString(16)})`);
  const gate = (flags & 1) === 1;
  if (gate !== isGateId(id)) return fail("bad_frame", `room frame ${id}: gate flag ${gate ? 1 : 0} does not match the id's kind`);
  const lod = v.getUint8(16);
  if (lod > maxLod) return fail("bad_frame", `room frame ${id}: lod ${lod} over max_lod ${maxLod}`);
  if (L < 1) return fail("bad_frame", `room frame ${id}: empty payload`);
  const origin = [v.getFloat64(24, true), v.getFloat64(32, true), v.getFloat64(40, true)];
  const centre = [v.getFloat64(48, true), v.getFloat64(56, true), v.getFloat64(64, true)];
  const radius = v.getFloat64(72, true);
  const LIM = 16777216;
  if (!finite3(origin) || !finite3(centre) || !Number.isFinite(radius) ||
      portals.some((p) => !finite3(p.centre) || !finite3(p.normal) || !Number.isFinite(p.radius)))
    return fail("bad_frame", `room frame ${id}: a double is not finite`);
  if (!origin.every(onGrid256)) return fail("bad_frame", `room frame ${id}: origin is not on the 1/256 m grid`);
  if (origin.some((x) => Math.abs(x) > LIM)) return fail("bad_frame", `room frame ${id}: origin beyond +/-2^24 m`);
  if (centre.some((x) => Math.abs(x) > LIM)) return fail("bad_frame", `room frame ${id}: centre beyond +/-2^24 m`);
  if (!(radius > 0 && radius <= 256)) return fail("bad_frame", `room frame ${id}: radius ${radius} outside (0, 256]`);
  for (let k = 0; k < 3; ++k)
    if (Math.abs(centre[k] - origin[k]) + radius > 32768)
      return fail("bad_frame", `room frame ${id}: the sphere reaches beyond 32768 m of the origin`);
  const seen = new Set();
  for (let i = 0; i < n; ++i) {
    const p = portals[i];
    if (p.to === id) return fail("bad_frame", `room frame ${id}: portal ${i} leads to the room itself`);
    if (seen.has(p.to)) return fail("bad_frame", `room frame ${id}: two portals to ${p.to}`);
    seen.add(p.to);
    const d = [p.centre[0] - centre[0], p.centre[1] - centre[1], p.centre[2] - centre[2]];
    if (Math.hypot(d[0], d[1], d[2]) > radius) return fail("bad_frame", `room frame ${id}: portal ${i}'s centre is outside the sphere`);
    const len = Math.hypot(p.normal[0], p.normal[1], p.normal[2]);
    if (!(Math.abs(len - 1) <= 1e-6)) return fail("bad_frame", `room frame ${id}: portal ${i}'s normal is not unit (length ${len})`);
    if (!(p.radius > 0 && p.radius <= radius)) return fail("bad_frame", `room frame ${id}: portal ${i}'s radius ${p.radius} outside (0, ${radius}]`);
  }
  const payload = bytes.subarray(HEADER_BYTES + PORTAL_BYTES * n, size);
  return { ok: true, frame: { id, idBinary, gate, lod, version, origin, centre, radius, portals, payload } };
}

// ---- Client messages ----

// queue: the viewer understands `queued` (PROTOCOL.md, "Waiting to enter"), so past its capacity a
// server holds it in its queue and says where, rather than refusing it.
export function helloMessage({ ref, seed, params, token, versions = VERSIONS_SPOKEN, name = CLIENT_NAME, queue = false } = {}) {
  const m = { type: "hello" };
  if (ref !== undefined) m.ref = ref;
  m.versions = versions.slice();
  if (seed !== undefined && seed !== null && seed !== "") m.seed = String(seed);
  if (params) m.params = params;
  m.name = name;
  if (token) m.token = token;
  if (queue) m.queue = true;
  return JSON.stringify(m);
}

export function spawnMessage(ref) {
  return JSON.stringify(ref === undefined ? { type: "spawn" } : { type: "spawn", ref });
}

export function locateMessage(point, ref) {
  const m = { type: "locate" };
  if (ref !== undefined) m.ref = ref;
  m.point = [point[0], point[1], point[2]];
  return JSON.stringify(m);
}

// rooms: [{id, lod, priority}]. Priorities are clamped to whole milliseconds in [0, 2^32 - 1].
export function requestMessage(rooms, ref) {
  const m = { type: "request" };
  if (ref !== undefined) m.ref = ref;
  m.rooms = rooms.map((r) => ({
    id: r.id,
    lod: r.lod | 0,
    priority: Math.min(4294967295, Math.max(0, Math.round(Number.isFinite(r.priority) ? r.priority : 4294967295))),
  }));
  return JSON.stringify(m);
}

export function cancelMessage(ids, ref) {
  const m = { type: "cancel" };
  if (ref !== undefined) m.ref = ref;
  m.rooms = ids.slice();
  return JSON.stringify(m);
}

export function pingMessage(t, ref) {
  const m = { type: "ping" };
  if (ref !== undefined) m.ref = ref;
  m.t = t;
  return JSON.stringify(m);
}

// ---- Server messages ----

const U64_RE = /^(0|[1-9][0-9]*)$/;
const U64_MAX = 18446744073709551615n;
const HEX16_RE = /^[0-9a-f]{16}$/;

export function isSeed(s) {
  return typeof s === "string" && U64_RE.test(s) && s.length <= 20 && BigInt(s) <= U64_MAX;
}

export function isParams(s) {
  return typeof s === "string" && HEX16_RE.test(s);
}

function isInt(x, lo, hi) {
  return typeof x === "number" && Number.isInteger(x) && x >= lo && x <= hi;
}

function isPosition(p) {
  return Array.isArray(p) && p.length === 3 && p.every((x) => typeof x === "number" && Number.isFinite(x) && Math.abs(x) <= 16777216);
}

function utf8Length(s) {
  return new TextEncoder().encode(s).length;
}

const MAX_SAFE = Number.MAX_SAFE_INTEGER;
const LIMIT_FIELDS = {
  max_message_bytes: [1024, MAX_SAFE, true],
  max_frame_bytes: [1024, MAX_SAFE, true],
  max_rooms_per_request: [1, MAX_SAFE, true],
  max_rooms_in_flight: [1, MAX_SAFE, true],
  request_rate: [1, MAX_SAFE, false],
  request_burst: [1, MAX_SAFE, false],
  max_kbps: [1, MAX_SAFE, false],
  max_lod: [0, 255, true],
  idle_timeout_ms: [1, MAX_SAFE, true],
  handshake_timeout_ms: [1, MAX_SAFE, true],
};

// Replaces every byte outside printable ASCII with '?' (PROTOCOL: error.message).
export function printable(s) {
  return String(s).replace(/[^\x20-\x7e]/g, "?");
}

// Checks a server text message (a string or an already parsed value). Returns {ok: true, msg} or
// {ok: false, message}. Unknown fields are ignored; an unknown error code reads as internal.
// queued.position and queued.queue, queued.wait_ms and error.retry_after_ms (PROTOCOL.md).
const MAX_QUEUE = 1000000;
const MAX_WAIT_MS = 86400000;

// What a queued player reads: "waiting to enter: 14th, about 20 s".
export function queuedText({ position, wait_ms: waitMs }) {
  const tens = position % 100;
  const suffix = tens >= 11 && tens <= 13 ? "th" : ({ 1: "st", 2: "nd", 3: "rd" }[position % 10] ?? "th");
  const s = Math.max(1, Math.round(waitMs / 1000));
  const about = s < 120 ? `${s} s` : `${Math.round(s / 60)} min`;
  return `waiting to enter: ${position}${suffix}, about ${about}`;
}

export function parseServerMessage(text) {
  let m = text;
  if (typeof text === "string") {
    try {
      m = JSON.parse(text);
    } catch {
      return { ok: false, message: "server message is not valid JSON" };
    }
  }
  if (m === null || typeof m !== "object" || Array.isArray(m)) return { ok: false, message: "server message is not an object" };
  if (typeof m.type !== "string") return { ok: false, message: "server message has no type" };
  const bad = (what) => ({ ok: false, message: `server message '${m.type}': ${what}` });
  if ("ref" in m && !isInt(m.ref, 0, MAX_SAFE)) return bad("ref is not an integer in [0, 2^53-1]");
  switch (m.type) {
    case "welcome": {
      if (!isInt(m.version, 1, 65535)) return bad("version is not an integer in [1, 65535]");
      if (typeof m.server !== "string" || utf8Length(m.server) > 64 || /[\x00-\x1f\x7f-\x9f]/.test(m.server)) return bad("server is not a string of at most 64 bytes");
      if (!isSeed(m.seed)) return bad("seed is not a decimal u64");
      if (!isParams(m.params)) return bad("params is not 16 lowercase hex digits");
      if (m.limits === null || typeof m.limits !== "object" || Array.isArray(m.limits)) return bad("limits is not an object");
      for (const [k, [lo, hi, required]] of Object.entries(LIMIT_FIELDS)) {
        if (!(k in m.limits)) {
          if (required) return bad(`limits.${k} is missing`);
          continue;
        }
        if (!isInt(m.limits[k], lo, hi)) return bad(`limits.${k} is not an integer in [${lo}, ${hi}]`);
      }
      return { ok: true, msg: m };
    }
    case "located":
      if (!isPosition(m.point)) return bad("point is not a position");
      if (m.room !== null && !isRoomId(m.room)) return bad("room is not a room id or null");
      return { ok: true, msg: m };
    case "spawn_point":
      if (!isRoomId(m.room)) return bad("room is not a room id");
      if (!isPosition(m.position)) return bad("position is not a position");
      return { ok: true, msg: m };
    case "error": {
      if (typeof m.code !== "string" || utf8Length(m.code) > 32) return bad("code is not a string of at most 32 bytes");
      if (typeof m.message !== "string") return bad("message is not a string");
      if (typeof m.fatal !== "boolean") return bad("fatal is not a boolean");
      if ("room" in m && !isRoomId(m.room)) return bad("room is not a room id");
      if ("versions" in m && !(Array.isArray(m.versions) && m.versions.every((x) => isInt(x, 1, 65535)))) return bad("versions is not a list of versions");
      if ("retry_after_ms" in m && !isInt(m.retry_after_ms, 0, MAX_WAIT_MS)) return bad("retry_after_ms is not an integer in [0, 86400000]");
      const known = new Set(["bad_json", "bad_message", "unknown_type", "unsupported_version", "too_large", "invalid_room_id", "not_found", "limit_exceeded", "world_mismatch", "out_of_order", "bad_frame", "unauthorized", "service_restart", "overloaded", "timeout", "internal"]);
      const msg = { ...m, message: printable(m.message).slice(0, 1024) };
      if (!known.has(m.code)) {
        msg.sent_code = m.code;
        msg.code = "internal";
      }
      return { ok: true, msg };
    }
    case "queued":
      if (!isInt(m.position, 1, MAX_QUEUE)) return bad("position is not an integer in [1, 1000000]");
      if (!isInt(m.wait_ms, 0, MAX_WAIT_MS)) return bad("wait_ms is not an integer in [0, 86400000]");
      if (!isInt(m.queue, m.position, MAX_QUEUE)) return bad("queue is not an integer in [position, 1000000]");
      return { ok: true, msg: m };
    case "pong":
      if (typeof m.t !== "number" || !Number.isFinite(m.t)) return bad("t is not a number");
      if (!isInt(m.time, 0, MAX_SAFE)) return bad("time is not an integer in [0, 2^53-1]");
      return { ok: true, msg: m };
    case "stats":
      for (const k of ["in_flight", "rooms_sent", "bytes_sent", "errors"]) if (!isInt(m[k], 0, MAX_SAFE)) return bad(`${k} is not an integer`);
      return { ok: true, msg: m };
    default:
      return bad("unknown message type");
  }
}

// What a close means for the client (PROTOCOL "After a close"): {stop, delayMs(attempt, random)}.
export const STOP_REASONS = new Set(["unsupported_version", "world_mismatch", "unauthorized"]);

export function shouldStop(reason) {
  return STOP_REASONS.has(reason);
}

// What the page says when the server refused it for good: the server's own words (`said`, the
// error's message, when it came) and what the reader can do. A reload cannot help with any of
// these, so none of them says to reload.
export function refusalText(reason, said) {
  const what = said ? `${reason}: ${said}` : reason;
  const todo = {
    world_mismatch: "this server does not serve that world; open the page without ?seed= for its own world, or run a server that serves more worlds (grotto-server --max-worlds)",
    unsupported_version: "this page and the server speak different protocol versions; open the page the server itself serves",
    unauthorized: "this server needs a token; open the page with ?token=YOUR_TOKEN",
  }[reason] || "the server will not serve this viewer";
  return `the server refused this viewer (${what}): stopped; ${todo}`;
}

// The delay before reconnect attempt `attempt` (0-based): after service_restart (1001) uniform in
// [50, 1000] ms; otherwise exponential backoff from 250 ms doubling to 15 s, with full jitter over
// its upper half. rand: a function giving [0, 1).
// retryAfterMs: the server's retry_after_ms with its overloaded refusal: never come back sooner.
export function reconnectDelay(attempt, { code, reason, retryAfterMs = 0 } = {}, rand = Math.random) {
  if (code === 1001 || reason === "service_restart") return 50 + rand() * 950;
  const base = Math.min(15000, 250 * 2 ** Math.min(attempt, 10));
  return Math.max(retryAfterMs, base / 2 + rand() * (base / 2));
}

// A place link: /?seed=95&pose=x,y,z,yaw,pitch (metres, radians), millimetres and milliradians.
// A place as links carry it, "x,y,z,yaw,pitch": metres, and degrees as grotto-client's --pose
// takes them (yaw 0 looks along -z, positive turns to +x), so a link's pose pastes into the native
// client. The page holds yaw and pitch in radians.
const DEG = Math.PI / 180;
export function formatPose(p) {
  const r = (x, k) => Number(x.toFixed(k)).toString();
  return [r(p.x, 3), r(p.y, 3), r(p.z, 3), r(p.yaw / DEG, 2), r(p.pitch / DEG, 2)].join(",");
}

export function parsePose(text) {
  if (typeof text !== "string") return null;
  const parts = text.split(",");
  if (parts.length !== 5 && parts.length !== 3) return null;
  const v = parts.map((s) => (s.trim() === "" ? NaN : Number(s)));
  if (v.some((x) => !Number.isFinite(x))) return null;
  if (v.slice(0, 3).some((x) => Math.abs(x) > 16777216)) return null;
  return { x: v[0], y: v[1], z: v[2], yaw: (v[3] ?? 0) * DEG, pitch: (v[4] ?? 0) * DEG };
}

// The formation kinds this viewer draws (PROTOCOL "Room extras over HTTP": 0 stalactite,
// 1 stalagmite, 2 column, 3 drapery, 4 boulder; a client ignores a kind it does not know).
export const FORMATION_KINDS = 5;
export const FORMATION_DRAPERY = 3;

// An extras resource's formations.data (16 numbers an instance) as a Float32Array of the
// instances whose kind is known, or null when the field is malformed or holds none.
export function knownFormations(formations) {
  const f = formations;
  if (!f || !Number.isInteger(f.count) || f.count <= 0 || !Array.isArray(f.data) || f.data.length < 16 * f.count) return null;
  const kept = [];
  for (let i = 0; i < f.count; ++i) {
    const one = f.data.slice(16 * i, 16 * i + 16);
    const kind = one[7];
    if (!one.every((v) => typeof v === "number" && Number.isFinite(v))) continue;
    if (!Number.isInteger(kind) || kind < 0 || kind >= FORMATION_KINDS) continue;
    kept.push(...one);
  }
  return kept.length ? Float32Array.from(kept) : null;
}
