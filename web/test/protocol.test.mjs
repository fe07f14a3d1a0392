// The frame parser, room ids, messages (web/src/protocol.js) under node's test runner.
import { test } from "node:test";
import assert from "node:assert/strict";
import fs from "node:fs";
import {
  parseRoomFrame, roomIdToBinary, roomIdFromBinary, parseRoomId, helloMessage, requestMessage,
  cancelMessage, pingMessage, locateMessage, spawnMessage, parseServerMessage, reconnectDelay,
  shouldStop, refusalText, parsePose, formatPose, knownFormations, queuedText,
} from "../src/protocol.js";

const fixture = new Uint8Array(fs.readFileSync(new URL("./fixtures/room_v2_7_0.0.0.r0.bin", import.meta.url)));

// A valid frame built here: room 1.-2.3.r5, two portals, a 4-byte payload.
function buildFrame({ n = 2, L = 4, id = "1.-2.3.r5", gate = false } = {}) {
  const buf = new ArrayBuffer(80 + 64 * n + L);
  const v = new DataView(buf);
  v.setUint32(0, 0x4f545247, true);
  v.setUint16(4, 2, true);
  v.setUint8(6, 1);
  v.setUint8(7, gate ? 1 : 0);
  v.setBigUint64(8, roomIdToBinary(id), true);
  v.setUint8(16, 0);
  v.setUint8(17, n);
  v.setUint16(18, 0, true);
  v.setUint32(20, L, true);
  [100, 50, -200].forEach((x, k) => v.setFloat64(24 + 8 * k, x, true)); // origin
  [110, 55, -190].forEach((x, k) => v.setFloat64(48 + 8 * k, x, true)); // centre
  v.setFloat64(72, 20, true);
  for (let i = 0; i < n; ++i) {
    const at = 80 + 64 * i;
    v.setBigUint64(at, roomIdToBinary(`1.-2.3.r${10 + i}`), true);
    [115 + i, 55, -190].forEach((x, k) => v.setFloat64(at + 8 + 8 * k, x, true));
    [1, 0, 0].forEach((x, k) => v.setFloat64(at + 32 + 8 * k, x, true));
    v.setFloat64(at + 56, 2, true);
  }
  new Uint8Array(buf, 80 + 64 * n).fill(7);
  return buf;
}

function expectFail(buf, code, re, opts) {
  const r = parseRoomFrame(buf, opts);
  assert.equal(r.ok, false, `expected ${code}`);
  assert.equal(r.code, code, r.message);
  if (re) assert.match(r.message, re);
}

test("a valid frame parses", () => {
  const r = parseRoomFrame(buildFrame());
  assert.ok(r.ok, r.message);
  assert.equal(r.frame.id, "1.-2.3.r5");
  assert.deepEqual(r.frame.origin, [100, 50, -200]);
  assert.equal(r.frame.portals.length, 2);
  assert.equal(r.frame.portals[1].to, "1.-2.3.r11");
  assert.equal(r.frame.payload.length, 4);
});

test("the server's real frame parses", () => {
  const r = parseRoomFrame(fixture);
  assert.ok(r.ok, r.message);
  assert.equal(r.frame.id, "0.0.0.r0");
  assert.equal(r.frame.version, 2);
  assert.deepEqual(r.frame.portals.map((p) => p.to), ["0.0.0.r3", "0.0.0.r34"]);
  assert.equal(r.frame.payload[0], "D".charCodeAt(0));
});

test("frame checks in PROTOCOL's order", () => {
  // 1. size
  expectFail(buildFrame(), "too_large", /max_frame_bytes/, { maxFrameBytes: 100 });
  // 2. magic (a too-large frame with a bad magic is too_large: size first)
  let b = buildFrame();
  new DataView(b).setUint8(0, 0);
  expectFail(b, "bad_frame", /magic/);
  expectFail(b, "too_large", null, { maxFrameBytes: 10 });
  expectFail(new ArrayBuffer(3), "bad_frame", /magic/);
  // 3. version
  b = buildFrame();
  new DataView(b).setUint16(4, 3, true);
  expectFail(b, "unsupported_version");
  new DataView(b).setUint8(0, 0); // magic before version
  expectFail(b, "bad_frame", /magic/);
  b = buildFrame();
  new DataView(b).setUint16(4, 1, true); // spoken, not the session's
  expectFail(b, "bad_frame", /session/);
  // 4. type
  b = buildFrame();
  new DataView(b).setUint8(6, 2);
  expectFail(b, "unknown_type");
  new DataView(b).setUint16(4, 9, true); // version before type
  expectFail(b, "unsupported_version");
  // 5. header present, n <= 16, exact size, reserved
  expectFail(buildFrame().slice(0, 79), "bad_frame", /80-byte header/);
  b = buildFrame();
  new DataView(b).setUint8(17, 17);
  expectFail(b, "bad_frame", /over 16/);
  expectFail(buildFrame().slice(0, 80 + 128 + 3), "bad_frame", /expected/);
  b = buildFrame();
  new DataView(b).setUint32(20, 5, true);
  expectFail(b, "bad_frame", /expected/);
  b = buildFrame();
  new DataView(b).setUint16(18, 1, true);
  expectFail(b, "bad_frame", /reserved/);
  new DataView(b).setUint8(6, 5); // type before reserved
  expectFail(b, "unknown_type");
  // 6. ids
  b = buildFrame();
  new DataView(b).setBigUint64(8, 0x1fffn, true); // slot 8191
  expectFail(b, "invalid_room_id");
  new DataView(b).setUint16(18, 1, true); // reserved before ids
  expectFail(b, "bad_frame", /reserved/);
  b = buildFrame();
  new DataView(b).setBigUint64(80 + 64, 0xffffffffffffffffn, true);
  expectFail(b, "invalid_room_id", /portal 1/);
  // 7. flags and the other rules
  b = buildFrame();
  new DataView(b).setUint8(7, 1); // gate flag on an interior room
  expectFail(b, "bad_frame", /gate flag/);
  new DataView(b).setBigUint64(8, 0x1fffn, true); // ids before flags
  expectFail(b, "invalid_room_id");
  expectFail(buildFrame({ id: "0.0.0.x1" }), "bad_frame", /gate flag/);
  assert.ok(parseRoomFrame(buildFrame({ id: "0.0.0.x1", gate: true })).ok);
  b = buildFrame();
  new DataView(b).setUint8(7, 2);
  expectFail(b, "bad_frame", /flag bits/);
  b = buildFrame();
  new DataView(b).setUint8(16, 1);
  expectFail(b, "bad_frame", /lod/);
  assert.ok(parseRoomFrame(b, { maxLod: 1 }).ok);
  for (const at of [24, 56, 72, 80 + 8, 80 + 32, 80 + 56]) {
    b = buildFrame();
    new DataView(b).setFloat64(at, NaN, true);
    expectFail(b, "bad_frame", /finite/);
    new DataView(b).setFloat64(at, Infinity, true);
    expectFail(b, "bad_frame", /finite/);
  }
  b = buildFrame();
  new DataView(b).setFloat64(24, 100.001, true);
  expectFail(b, "bad_frame", /grid/);
  b = buildFrame();
  new DataView(b).setFloat64(72, 0, true);
  expectFail(b, "bad_frame", /radius/);
  new DataView(b).setFloat64(72, 256.5, true);
  expectFail(b, "bad_frame", /radius/);
  b = buildFrame();
  new DataView(b).setFloat64(24, 20000000, true);
  expectFail(b, "bad_frame", /2\^24/);
  b = buildFrame();
  new DataView(b).setFloat64(48, 40000, true);
  expectFail(b, "bad_frame", /32768/);
  b = buildFrame();
  new DataView(b).setBigUint64(80, roomIdToBinary("1.-2.3.r5"), true);
  expectFail(b, "bad_frame", /itself/);
  b = buildFrame();
  new DataView(b).setBigUint64(80 + 64, roomIdToBinary("1.-2.3.r10"), true);
  expectFail(b, "bad_frame", /two portals/);
  b = buildFrame();
  new DataView(b).setFloat64(80 + 8, 200, true);
  expectFail(b, "bad_frame", /outside the sphere/);
  b = buildFrame();
  new DataView(b).setFloat64(80 + 32, 1.00001, true);
  expectFail(b, "bad_frame", /not unit/);
  new DataView(b).setFloat64(80 + 32, 1 + 5e-7, true);
  assert.ok(parseRoomFrame(b).ok);
  b = buildFrame();
  new DataView(b).setFloat64(80 + 56, 21, true);
  expectFail(b, "bad_frame", /radius/);
  new DataView(b).setFloat64(80 + 56, -1, true);
  expectFail(b, "bad_frame", /radius/);
  expectFail(buildFrame({ L: 0 }), "bad_frame", /empty payload/);
  expectFail("not binary", "bad_frame");
});

test("room ids: text and binary round trips", () => {
  for (const id of ["0.0.0.r0", "3.-1.0.r12", "-2.0.5.y1", "65535.-65535.65535.r4095", "-65535.65535.-65535.z15", "0.0.0.x0"]) {
    const b = roomIdToBinary(id);
    assert.equal(typeof b, "bigint");
    assert.equal(roomIdFromBinary(b), id);
  }
  assert.equal(roomIdToBinary("0.0.0.r0"), (65535n << 13n) | (65535n << 30n) | (65535n << 47n));
  assert.equal(roomIdToBinary("0.0.0.x0") & 0x1fffn, 4096n);
  assert.equal(roomIdToBinary("0.0.0.z15") & 0x1fffn, 4096n + 32n + 15n);
  // The fixture's id field.
  assert.equal(roomIdFromBinary(new DataView(fixture.buffer, fixture.byteOffset).getBigUint64(8, true)), "0.0.0.r0");
});

test("room ids: rejects", () => {
  for (const bad of ["", "0.0.0", "0.0.0.r", "00.0.0.r0", "0.01.0.r0", "-0.0.0.r0", "0.0.0.r01", "+1.0.0.r0", "0.0.0.r4096", "0.0.0.x16",
    "65536.0.0.r0", "0.-65536.0.r0", "0.0.0.w1", "0.0.0.r-1", " 0.0.0.r0", "0.0.0.r0 ", "0.0.0.0.r0", "1".repeat(60) + ".0.0.r0", "0.0.0.r1e3", "0x1.0.0.r0"]) {
    assert.equal(parseRoomId(bad), null, bad);
    assert.equal(roomIdToBinary(bad), null, bad);
  }
  assert.equal(parseRoomId("0.0.0.r" + "0".repeat(60)), null); // > 64 chars
  assert.equal(roomIdFromBinary(4144n), null); // slot out of range
  assert.equal(roomIdFromBinary(0x1ffffn << 13n), null); // sx field 131071
  assert.equal(roomIdFromBinary(-1n), null);
  assert.equal(roomIdFromBinary(1n << 64n), null);
  assert.equal(roomIdFromBinary(0n), "-65535.-65535.-65535.r0");
});

test("client messages", () => {
  assert.deepEqual(JSON.parse(helloMessage({ ref: 1, seed: "7" })), { type: "hello", ref: 1, versions: [2], seed: "7", name: "grotto-viewer 0.3.0" });
  assert.deepEqual(JSON.parse(helloMessage({ token: "s3cret" })).token, "s3cret");
  assert.ok(!("seed" in JSON.parse(helloMessage({}))));
  assert.equal(JSON.parse(helloMessage({ queue: true })).queue, true);
  assert.ok(!("queue" in JSON.parse(helloMessage({}))));
  assert.deepEqual(JSON.parse(requestMessage([{ id: "0.0.0.r0", lod: 0, priority: 12.6 }, { id: "0.0.0.r1", lod: 0, priority: -4 }, { id: "0.0.0.r2", lod: 0, priority: 1e12 }], 5)), {
    type: "request", ref: 5, rooms: [{ id: "0.0.0.r0", lod: 0, priority: 13 }, { id: "0.0.0.r1", lod: 0, priority: 0 }, { id: "0.0.0.r2", lod: 0, priority: 4294967295 }],
  });
  assert.deepEqual(JSON.parse(cancelMessage(["0.0.0.r3"], 6)), { type: "cancel", ref: 6, rooms: ["0.0.0.r3"] });
  assert.deepEqual(JSON.parse(pingMessage(12.5, 7)), { type: "ping", ref: 7, t: 12.5 });
  assert.deepEqual(JSON.parse(locateMessage([1, 2, 3], 8)), { type: "locate", ref: 8, point: [1, 2, 3] });
  assert.deepEqual(JSON.parse(spawnMessage(9)), { type: "spawn", ref: 9 });
});

const WELCOME = { type: "welcome", ref: 1, version: 2, server: "grotto-server 0.3.0", seed: "7", params: "5d1c0a2e9b7f3c44",
  limits: { max_message_bytes: 65536, max_frame_bytes: 4194304, max_rooms_per_request: 256, max_rooms_in_flight: 1024, max_lod: 0, idle_timeout_ms: 60000, handshake_timeout_ms: 5000, request_rate: 2000, request_burst: 4000 } };

test("server messages: welcome and its limits", () => {
  assert.ok(parseServerMessage(JSON.stringify(WELCOME)).ok);
  const w = (patch, limits) => parseServerMessage({ ...WELCOME, ...patch, limits: { ...WELCOME.limits, ...limits } });
  assert.ok(w({}, { request_rate: undefined }).ok === false); // present but not an integer
  const noRate = { ...WELCOME, limits: { ...WELCOME.limits } };
  delete noRate.limits.request_rate;
  delete noRate.limits.request_burst;
  assert.ok(parseServerMessage(noRate).ok, "optional limits may be absent");
  const noLod = { ...WELCOME, limits: { ...WELCOME.limits } };
  delete noLod.limits.max_lod;
  assert.equal(parseServerMessage(noLod).ok, false);
  assert.equal(w({}, { max_message_bytes: 1023 }).ok, false);
  assert.equal(w({}, { max_frame_bytes: 100 }).ok, false);
  assert.equal(w({}, { max_rooms_per_request: 0 }).ok, false);
  assert.equal(w({}, { max_rooms_in_flight: 1.5 }).ok, false);
  assert.equal(w({}, { max_lod: 256 }).ok, false);
  assert.equal(w({}, { idle_timeout_ms: 0 }).ok, false);
  assert.equal(w({}, { max_kbps: 0 }).ok, false);
  assert.ok(w({}, { max_kbps: 100 }).ok);
  assert.equal(w({ version: 0 }).ok, false);
  assert.equal(w({ seed: "07" }).ok, false);
  assert.equal(w({ seed: "18446744073709551616" }).ok, false);
  assert.ok(w({ seed: "18446744073709551615" }).ok);
  assert.equal(w({ params: "5D1C0A2E9B7F3C44" }).ok, false);
  assert.equal(w({ server: "x".repeat(65) }).ok, false);
  assert.ok(w({ extra_field: { anything: 1 } }).ok, "unknown fields are ignored");
  assert.equal(parseServerMessage("{not json").ok, false);
  assert.equal(parseServerMessage("[]").ok, false);
  assert.equal(parseServerMessage('{"type":"teleport"}').ok, false);
});

test("server messages: error, pong, located, spawn_point", () => {
  const e = parseServerMessage({ type: "error", ref: 13, code: "invalid_room_id", message: "rooms[0].id: malformed", fatal: false });
  assert.ok(e.ok);
  assert.equal(e.msg.code, "invalid_room_id");
  const unknown = parseServerMessage({ type: "error", code: "brand_new", message: "caf\u00e9", fatal: true });
  assert.ok(unknown.ok);
  assert.equal(unknown.msg.code, "internal");
  assert.equal(unknown.msg.fatal, true);
  assert.equal(unknown.msg.message, "caf?");
  assert.equal(parseServerMessage({ type: "error", code: "x", message: "m" }).ok, false); // no fatal
  assert.equal(parseServerMessage({ type: "error", code: "not_found", message: "m", fatal: false, room: "bad" }).ok, false);
  assert.ok(parseServerMessage({ type: "pong", ref: 16, t: 1732339200123.5, time: 1732339200131 }).ok);
  assert.equal(parseServerMessage({ type: "pong", t: 1, time: -1 }).ok, false);
  assert.equal(parseServerMessage({ type: "pong", t: "x", time: 1 }).ok, false);
  assert.ok(parseServerMessage({ type: "located", point: [1, 2, 3], room: null }).ok);
  assert.ok(parseServerMessage({ type: "located", point: [1, 2, 3], room: "0.0.0.r3" }).ok);
  assert.equal(parseServerMessage({ type: "located", point: [1, 2], room: null }).ok, false);
  assert.ok(parseServerMessage({ type: "spawn_point", ref: 2, room: "0.0.0.r0", position: [47.9, 48.3, 48.1] }).ok);
  assert.equal(parseServerMessage({ type: "spawn_point", room: "0.0.0.r0", position: [1e30, 0, 0] }).ok, false);
  assert.equal(parseServerMessage({ type: "pong", ref: -1, t: 1, time: 1 }).ok, false);
});

test("a refusal says why, in the server's words, and what to do instead of reloading", () => {
  const t = refusalText("world_mismatch", "this server serves seed 7, not 95");
  assert.match(t, /world_mismatch: this server serves seed 7, not 95/);
  assert.match(t, /without \?seed=|--max-worlds/);
  assert.doesNotMatch(t, /reload/);
  for (const r of ["unsupported_version", "unauthorized"]) assert.doesNotMatch(refusalText(r), /reload/);
  assert.match(refusalText("unauthorized"), /token/);
});

test("after a close: stop or reconnect with backoff and jitter", () => {
  for (const r of ["unsupported_version", "world_mismatch", "unauthorized"]) assert.ok(shouldStop(r));
  for (const r of ["timeout", "service_restart", "", "overloaded", "bad_frame"]) assert.ok(!shouldStop(r));
  for (const x of [0, 0.5, 0.999]) {
    const d = reconnectDelay(3, { code: 1001, reason: "service_restart" }, () => x);
    assert.ok(d >= 50 && d <= 1000, String(d));
  }
  const d0 = [0, 1, 2, 3, 10, 30].map((a) => reconnectDelay(a, { code: 1006 }, () => 0.999));
  for (let i = 1; i < d0.length; ++i) assert.ok(d0[i] >= d0[i - 1]);
  assert.ok(d0[d0.length - 1] <= 15000);
  assert.ok(reconnectDelay(0, {}, () => 0) >= 125);
  assert.notEqual(reconnectDelay(4, {}, () => 0), reconnectDelay(4, {}, () => 0.9), "jitter");
});

test("place links", () => {
  // Degrees in the link, as grotto-client's --pose; radians in the page.
  const p = parsePose("12.5,-3,40.25,90,-45");
  assert.deepEqual(p, { x: 12.5, y: -3, z: 40.25, yaw: Math.PI / 2, pitch: -Math.PI / 4 });
  assert.equal(formatPose({ x: 1.23456, y: 2, z: -3, yaw: Math.PI, pitch: 0.1 }), "1.235,2,-3,180,5.73");
  const back = parsePose(formatPose({ x: 1.23456, y: 2, z: -3, yaw: 0.123456, pitch: 0 }));
  assert.ok(Math.abs(back.yaw - 0.123456) < 1e-3 && back.x === 1.235);
  assert.equal(parsePose("1,2"), null);
  assert.equal(parsePose("1,2,x,0,0"), null);
  assert.equal(parsePose("1,2,,0,0"), null);
  assert.equal(parsePose("1e30,0,0,0,0"), null);
});

test("extras' formations: the known kinds kept, an unknown kind or a malformed instance dropped", () => {
  const one = (kind, x = 1) => [x, 2, 3, 1.5, 0.4, 0.01, 0.3, kind, 0.1, 3, 0.2, 0.8, 0.5, 1.2, 0, 0];
  const data = [...one(0), ...one(3, 7), ...one(9), ...one(2.5), ...one(1).map((v, i) => (i === 4 ? null : v)), ...one(1, 11), ...one(4, 13)];
  const kept = knownFormations({ count: 7, data });
  assert.ok(kept instanceof Float32Array);
  assert.equal(kept.length, 4 * 16);
  assert.deepEqual([kept[0], kept[16], kept[32], kept[48]], [1, 7, 11, 13]);
  assert.deepEqual([kept[7], kept[23], kept[39], kept[55]], [0, 3, 1, 4], "a boulder (kind 4) is drawn");
  assert.equal(knownFormations({ count: 2, data: one(0) }), null, "fewer numbers than count says");
  assert.equal(knownFormations({ count: 1, data: one(5) }), null, "no known kind: nothing to draw");
  assert.equal(knownFormations(undefined), null);
});

test("queued: parsed strictly, shown as a place and a wait", () => {
  const ok = parseServerMessage('{"type":"queued","ref":1,"position":14,"wait_ms":20000,"queue":30}');
  assert.ok(ok.ok, ok.message);
  assert.equal(queuedText(ok.msg), "waiting to enter: 14th, about 20 s");
  assert.equal(queuedText({ position: 1, wait_ms: 400 }), "waiting to enter: 1st, about 1 s");
  assert.equal(queuedText({ position: 22, wait_ms: 2000 }), "waiting to enter: 22nd, about 2 s");
  assert.equal(queuedText({ position: 113, wait_ms: 600000 }), "waiting to enter: 113th, about 10 min");
  for (const bad of [
    '{"type":"queued","position":0,"wait_ms":0,"queue":1}',
    '{"type":"queued","position":3,"wait_ms":0,"queue":2}',
    '{"type":"queued","position":1,"wait_ms":-1,"queue":1}',
    '{"type":"queued","position":1,"queue":1}',
    '{"type":"error","code":"overloaded","message":"x","fatal":true,"retry_after_ms":"5"}',
  ]) {
    assert.equal(parseServerMessage(bad).ok, false, bad);
  }
  const refused = parseServerMessage('{"type":"error","code":"overloaded","message":"full","fatal":true,"retry_after_ms":7000}');
  assert.ok(refused.ok);
  assert.equal(refused.msg.retry_after_ms, 7000);
  assert.ok(reconnectDelay(0, { code: 1008, reason: "overloaded", retryAfterMs: 7000 }, () => 0.5) >= 7000);
  assert.ok(reconnectDelay(0, { code: 1008, reason: "overloaded" }, () => 0.5) < 7000);
});
