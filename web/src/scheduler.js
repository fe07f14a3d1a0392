// Which rooms to ask for, which to cancel and which to evict: the portal graph walked from the
// player's room by time to reach (PROTOCOL "Rooms in flight": priority = milliseconds until the
// player can reach the room). Pure: node's tests drive it (web/test/scheduler.test.mjs).
//
// Time to reach a room: the shortest path over portal centres (from the player's position to a
// portal of the room the player is in, then portal to portal across each room) at walking speed,
// plus the time to turn towards the first portal (a room behind the player costs a turn), so that
// turning back brings the rooms behind into the horizon and sends the ones ahead out of it.

export const DEFAULTS = {
  speed: 4.0, // m/s: walking (flying at twice that asks further)
  // Radians a second of the turn to face a room's first portal: a room straight behind costs 6 s
  // more than one ahead (the player walks where it looks), so turning back sends the far rooms
  // ahead out of the cancel horizon and brings the ones behind in.
  turnRate: Math.PI / 6,
  horizonMs: 14000, // rooms reachable within this are wanted
  cancelMs: 16000, // rooms in flight beyond this are cancelled (hysteresis)
  maxRooms: 400, // the room store's cap: beyond it the farthest rooms are evicted
};

function dist(a, b) {
  return Math.hypot(a[0] - b[0], a[1] - b[1], a[2] - b[2]);
}

// rooms: Map id -> {centre, radius, portals: [{to, centre}]} of the rooms whose descriptor is
// known (loaded). here: the room id the player is in (its descriptor may be unknown yet).
// position: [x,y,z]; forward: unit [x,y,z] (horizontal is enough). Returns Map id -> ms for every
// room reached within limitMs, including known rooms' neighbours whose descriptor is unknown.
export function timesToReach(rooms, here, position, forward, opts = {}) {
  const o = { ...DEFAULTS, ...opts };
  const limit = opts.limitMs ?? o.cancelMs;
  const out = new Map();
  if (!here) return out;
  out.set(here, 0);
  const start = rooms.get(here);
  if (!start) return out;
  // Dijkstra over (room, entry point); small graphs: a sorted array as the queue.
  const queue = [];
  const best = new Map([[here, 0]]);
  const turnCost = (target) => {
    const d = [target[0] - position[0], target[1] - position[1], target[2] - position[2]];
    const len = Math.hypot(d[0], d[2]);
    const f = Math.hypot(forward[0], forward[2]);
    if (len < 1e-6 || f < 1e-6) return 0;
    const c = (d[0] * forward[0] + d[2] * forward[2]) / (len * f);
    return (Math.acos(Math.max(-1, Math.min(1, c))) / o.turnRate) * 1000;
  };
  for (const p of start.portals) {
    const t = (dist(position, p.centre) / o.speed) * 1000 + turnCost(p.centre);
    queue.push({ id: p.to, at: p.centre, t, from: here });
  }
  while (queue.length) {
    let k = 0;
    for (let i = 1; i < queue.length; ++i) if (queue[i].t < queue[k].t) k = i;
    const cur = queue[k];
    queue[k] = queue[queue.length - 1];
    queue.pop();
    if (cur.t > limit) continue;
    const prev = best.get(cur.id);
    if (prev !== undefined && prev <= cur.t) continue;
    best.set(cur.id, cur.t);
    out.set(cur.id, cur.t);
    const room = rooms.get(cur.id);
    if (!room) continue;
    for (const p of room.portals) {
      if (p.to === cur.from && best.has(p.to)) continue;
      const t = cur.t + (dist(cur.at, p.centre) / o.speed) * 1000;
      const b = best.get(p.to);
      if (t <= limit && (b === undefined || t < b)) queue.push({ id: p.to, at: p.centre, t, from: cur.id });
    }
  }
  return out;
}

// One planning step. state: {loaded: Set, inFlight: Map id -> {priority, sent}, failed: Map id ->
// retry-after time (ms)}; times: timesToReach's map; limits: {maxRoomsInFlight,
// maxRoomsPerRequest, tokens (request-rate tokens available, Infinity if none)}; now: ms.
// Returns {request: [{id, priority}], cancel: [id], evict: [id]} within the limits: requests by
// ascending time to reach, never over max_rooms_in_flight, at most max_rooms_per_request a
// message (one message each step), cancels for rooms in flight beyond the cancel horizon, evictions
// of the loaded rooms farthest away (unreached first) while more than maxRooms are loaded.
export function plan(state, times, limits, now = 0, opts = {}) {
  const o = { ...DEFAULTS, ...opts };
  const perMessage = Math.max(1, limits.maxRoomsPerRequest ?? 256);
  const cancel = [];
  for (const [id] of state.inFlight) {
    const t = times.get(id);
    if ((t === undefined || t > o.cancelMs) && cancel.length < perMessage) cancel.push(id);
  }
  const inFlightAfter = state.inFlight.size - cancel.length;
  let room = Math.max(0, (limits.maxRoomsInFlight ?? 1024) - inFlightAfter);
  room = Math.min(room, perMessage);
  if (Number.isFinite(limits.tokens)) room = Math.min(room, Math.max(0, Math.floor(limits.tokens) - cancel.length));
  const wanted = [];
  for (const [id, t] of times) {
    if (t > o.horizonMs) continue;
    if (state.loaded.has(id) || state.inFlight.has(id)) continue;
    const retry = state.failed?.get(id);
    if (retry !== undefined && retry > now) continue;
    wanted.push({ id, priority: Math.round(t) });
  }
  wanted.sort((a, b) => a.priority - b.priority || (a.id < b.id ? -1 : a.id > b.id ? 1 : 0));
  const request = wanted.slice(0, room);
  const evict = [];
  if (state.loaded.size > o.maxRooms) {
    const order = [...state.loaded].map((id) => ({ id, t: times.has(id) ? times.get(id) : Infinity }));
    order.sort((a, b) => b.t - a.t);
    for (let i = 0; i < state.loaded.size - o.maxRooms; ++i) evict.push(order[i].id);
  }
  return { request, cancel, evict };
}

// A token bucket like the server's (request_rate a second, request_burst at most; cancels may
// take it one burst below zero).
export class TokenBucket {
  constructor(rate, burst, now = 0) {
    this.rate = rate ?? Infinity;
    this.burst = burst ?? Infinity;
    this.tokens = this.burst;
    this.at = now;
  }
  refill(now) {
    if (!Number.isFinite(this.rate)) return;
    this.tokens = Math.min(this.burst, this.tokens + ((now - this.at) / 1000) * this.rate);
    this.at = now;
  }
  available(now) {
    this.refill(now);
    return this.tokens;
  }
  take(n, now) {
    this.refill(now);
    if (Number.isFinite(this.tokens)) this.tokens = Math.max(-this.burst, this.tokens - Math.max(1, n));
  }
}
