// The request scheduler (web/src/scheduler.js): priority by time to reach, the limits, cancels when
// the player turns back, eviction of the farthest rooms.
import { test } from "node:test";
import assert from "node:assert/strict";
import { timesToReach, plan, TokenBucket } from "../src/scheduler.js";

// A corridor of rooms along x: ... w2 - w1 - r0 - e1 - e2 ... 20 m apart, portals half way.
function corridor(known) {
  const rooms = new Map();
  for (let i = -6; i <= 6; ++i) {
    const id = (k) => (k === 0 ? "r0" : k > 0 ? `e${k}` : `w${-k}`);
    if (!known(i)) continue;
    rooms.set(id(i), {
      centre: [20 * i, 0, 0], radius: 12,
      portals: [{ to: id(i - 1), centre: [20 * i - 10, 0, 0] }, { to: id(i + 1), centre: [20 * i + 10, 0, 0] }],
    });
  }
  return rooms;
}

test("time to reach: walking distance over the portal graph, plus a turn", () => {
  const rooms = corridor(() => true);
  const east = timesToReach(rooms, "r0", [0, 0, 0], [1, 0, 0], { speed: 4, turnRate: Math.PI / 2, cancelMs: 1e9 });
  assert.equal(east.get("r0"), 0);
  assert.equal(east.get("e1"), 2500); // 10 m at 4 m/s, no turn
  assert.equal(east.get("e2"), 7500); // + 20 m
  assert.equal(east.get("w1"), 4500); // 10 m and a half turn (2 s)
  assert.ok(east.get("w2") > east.get("e2"));
  // Unknown descriptors end the walk: their neighbours' times are unknown.
  const partial = timesToReach(corridor((i) => i >= -1 && i <= 1), "r0", [0, 0, 0], [1, 0, 0], { cancelMs: 1e9 });
  assert.ok(partial.has("e2") && !partial.has("e3"));
});

test("plan: requests by ascending time, within max_rooms_in_flight and max_rooms_per_request", () => {
  const rooms = corridor(() => true);
  const times = timesToReach(rooms, "r0", [0, 0, 0], [1, 0, 0], { cancelMs: 1e9 });
  const state = { loaded: new Set(["r0"]), inFlight: new Map(), failed: new Map() };
  let out = plan(state, times, { maxRoomsInFlight: 100, maxRoomsPerRequest: 100 }, 0, { horizonMs: 1e9, cancelMs: 1e9 });
  const pr = out.request.map((r) => r.priority);
  assert.deepEqual(pr, [...pr].sort((a, b) => a - b));
  assert.equal(out.request[0].id, "e1");
  assert.ok(!out.request.some((r) => r.id === "r0"), "loaded rooms are not asked again");
  out = plan(state, times, { maxRoomsInFlight: 100, maxRoomsPerRequest: 3 }, 0, { horizonMs: 1e9 });
  assert.equal(out.request.length, 3);
  state.inFlight.set("e1", { priority: 2500 });
  state.inFlight.set("e2", { priority: 7500 });
  out = plan(state, times, { maxRoomsInFlight: 4, maxRoomsPerRequest: 100 }, 0, { horizonMs: 1e9, cancelMs: 1e9 });
  assert.equal(out.request.length, 2, "never over max_rooms_in_flight");
  assert.ok(!out.request.some((r) => r.id === "e1" || r.id === "e2"), "rooms in flight are not asked again");
  out = plan(state, times, { maxRoomsInFlight: 100, maxRoomsPerRequest: 100, tokens: 1 }, 0, { horizonMs: 1e9, cancelMs: 1e9 });
  assert.equal(out.request.length, 1, "the request-rate bucket");
  // A room refused recently waits.
  state.failed.set("w1", 5000);
  out = plan(state, times, { maxRoomsInFlight: 100, maxRoomsPerRequest: 100 }, 1000, { horizonMs: 1e9, cancelMs: 1e9 });
  assert.ok(!out.request.some((r) => r.id === "w1"));
  out = plan(state, times, { maxRoomsInFlight: 100, maxRoomsPerRequest: 100 }, 6000, { horizonMs: 1e9, cancelMs: 1e9 });
  assert.ok(out.request.some((r) => r.id === "w1"));
});

test("plan: asks ahead, and cancels what falls out of the horizon when the player turns back", () => {
  const rooms = corridor(() => true);
  const opts = { speed: 4, turnRate: Math.PI / 2, horizonMs: 9000, cancelMs: 11000 };
  const state = { loaded: new Set(["r0"]), inFlight: new Map(), failed: new Map() };
  // Facing east, a few steps east of the centre: e1, e2 and w1 are within 9 s; w2 is not
  // (10 m + 4 m ... plus a half turn).
  let times = timesToReach(rooms, "r0", [4, 0, 0], [1, 0, 0], opts);
  let out = plan(state, times, { maxRoomsInFlight: 100, maxRoomsPerRequest: 100 }, 0, opts);
  const asked = out.request.map((r) => r.id);
  assert.ok(asked.includes("e1") && asked.includes("e2"));
  assert.ok(!asked.includes("w2"));
  for (const r of out.request) state.inFlight.set(r.id, { priority: r.priority });
  assert.deepEqual(out.cancel, []);
  // Turned round and walked west: e2 (and what lies beyond) falls out and is cancelled.
  times = timesToReach(rooms, "r0", [-8, 0, 0], [-1, 0, 0], opts);
  out = plan(state, times, { maxRoomsInFlight: 100, maxRoomsPerRequest: 100 }, 0, opts);
  assert.ok(out.cancel.includes("e2"), JSON.stringify(out));
  assert.ok(!out.cancel.includes("e1"), "within the cancel horizon: kept");
  assert.ok(out.request.some((r) => r.id === "w2"), "the rooms ahead now");
});

test("plan: the room store is bounded: the farthest rooms are evicted", () => {
  const rooms = corridor(() => true);
  const times = timesToReach(rooms, "r0", [0, 0, 0], [1, 0, 0], { cancelMs: 1e9 });
  const loaded = new Set(["r0", "e1", "e2", "e3", "w1", "w5", "elsewhere"]);
  const out = plan({ loaded, inFlight: new Map() }, times, { maxRoomsInFlight: 10, maxRoomsPerRequest: 10 }, 0, { maxRooms: 4, cancelMs: 1e9 });
  assert.equal(out.evict.length, 3);
  assert.equal(out.evict[0], "elsewhere"); // unreachable first
  assert.ok(out.evict.includes("w5"));
  assert.ok(!out.evict.includes("r0"));
});

test("token bucket", () => {
  const b = new TokenBucket(10, 20, 0);
  assert.equal(b.available(0), 20);
  b.take(20, 0);
  assert.equal(b.available(0), 0);
  assert.equal(b.available(500), 5);
  b.take(30, 500);
  assert.equal(b.available(500), -20); // a burst below zero at most
  const none = new TokenBucket(undefined, undefined);
  assert.equal(none.available(0), Infinity);
});
