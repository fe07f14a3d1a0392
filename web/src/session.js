// One player's session with grotto-server (proto/PROTOCOL.md, version 2): the WebSocket, hello and
// welcome, spawn or locate, requests ahead of the player by time to reach over the portal graph
// (scheduler.js), cancels of rooms that fell out of the horizon, the request-rate bucket, pings
// within idle_timeout_ms, errors, and reconnects with backoff and jitter (50 ms - 1 s after
// service_restart); it stops after unsupported_version, world_mismatch or unauthorized (asking for
// a token after unauthorized). Room frames are parsed and checked here (protocol.js) and handed to
// the viewer, which decodes them in the worker; the room store (what is loaded) is the viewer's.
import {
  parseRoomFrame, parseServerMessage, helloMessage, spawnMessage, locateMessage, requestMessage,
  cancelMessage, pingMessage, shouldStop, refusalText, reconnectDelay, queuedText,
} from "./protocol.js";
import { timesToReach, plan, TokenBucket, DEFAULTS } from "./scheduler.js";

export class Session {
  // opts: {url, seed, token, lod, hooks: {onWelcome(msg, first), onSpawn(room, position),
  // onLocated(room, point), onFrame(frame), onError(text), onStatus(status, text), needToken()
  // -> string|null}, player() -> {room, position, forward, speed}, store: {loaded: Set, descriptors:
  // Map id -> {centre, radius, portals}}}
  constructor(opts) {
    this.o = opts;
    this.hooks = opts.hooks || {};
    this.status = "connecting";
    this.ws = null;
    this.version = 2;
    this.limits = null;
    this.inFlight = new Map(); // id -> {priority, sent, lod, ref}
    this.failed = new Map(); // id -> ms before which it is not asked again
    this.counts = { requests: 0, cancels: 0, reconnects: 0, errors: 0, frames: 0, badFrames: 0 };
    this.attempt = 0;
    this.ref = 1;
    this.refs = new Map(); // ref -> {kind, rooms?}
    this.params = null;
    this.welcomed = false;
    this.pendingLocate = null;
    this.stopped = false;
    this.lod = opts.lod ?? 0;
    this.pausedUntil = 0;
    this.timers = [];
    this.bucket = new TokenBucket(Infinity, Infinity);
    this.lastSent = 0;
  }

  now() {
    return performance.now();
  }

  setStatus(s, text) {
    this.status = s;
    this.hooks.onStatus?.(s, text);
  }

  error(text) {
    this.counts.errors++;
    this.hooks.onError?.(text);
  }

  connect() {
    if (this.stopped) return;
    this.welcomed = false;
    this.inFlight.clear(); // the server forgets a closed connection's rooms in flight
    this.refs.clear();
    let ws;
    try {
      ws = new WebSocket(this.o.url);
    } catch (e) {
      this.error(`cannot open ${this.o.url}: ${e.message}`);
      this.scheduleReconnect({});
      return;
    }
    ws.binaryType = "arraybuffer";
    this.ws = ws;
    ws.onopen = () => {
      const token = this.o.token || undefined;
      this.send(helloMessage({ ref: this.nextRef("hello"), seed: this.o.seed, token, queue: true }));
    };
    ws.onmessage = (ev) => {
      if (ws !== this.ws) return;
      if (typeof ev.data === "string") this.onText(ev.data);
      else this.onBinary(ev.data);
    };
    ws.onerror = () => {};
    ws.onclose = (ev) => {
      if (ws !== this.ws) return;
      this.ws = null;
      this.onClose(ev.code, ev.reason);
    };
  }

  nextRef(kind, rooms) {
    const r = this.ref++;
    this.refs.set(r, { kind, rooms });
    if (this.refs.size > 4096) this.refs.delete(this.refs.keys().next().value);
    return r;
  }

  send(text) {
    if (!this.ws || this.ws.readyState !== 1) return false;
    if (this.limits && text.length > this.limits.max_message_bytes) return false;
    this.ws.send(text);
    this.lastSent = this.now();
    return true;
  }

  onText(text) {
    const r = parseServerMessage(text);
    if (!r.ok) {
      this.error(`server message refused: ${r.message}`);
      return;
    }
    const m = r.msg;
    switch (m.type) {
      case "welcome": {
        const first = this.params === null;
        if (!first && m.params !== this.params) this.hooks.onWorldChanged?.();
        this.params = m.params;
        this.version = m.version;
        this.limits = m.limits;
        this.lod = Math.min(this.o.lod ?? 0, m.limits.max_lod);
        this.bucket = new TokenBucket(m.limits.request_rate, m.limits.request_burst, this.now());
        this.welcomed = true;
        this.queued = null;
        this.attempt = 0;
        this.setStatus("open", "");
        this.hooks.onWelcome?.(m, first);
        this.startTimers();
        break;
      }
      case "spawn_point":
        this.hooks.onSpawn?.(m.room, m.position);
        break;
      case "located":
        this.pendingLocate = null;
        this.hooks.onLocated?.(m.room, m.point);
        break;
      case "queued":
        // Past the server's capacity: our place in its queue; welcome follows when it is our turn.
        this.queued = { position: m.position, wait_ms: m.wait_ms, queue: m.queue };
        this.setStatus("queued", queuedText(m));
        break;
      case "pong":
        break;
      case "stats":
        break;
      case "error":
        this.onServerError(m);
        break;
    }
  }

  onServerError(m) {
    const about = m.ref !== undefined ? this.refs.get(m.ref) : undefined;
    if (m.room) {
      // One room refused: not in flight any more; ask again later (not_found: much later).
      this.inFlight.delete(m.room);
      this.failed.set(m.room, this.now() + (m.code === "not_found" ? 120000 : 3000));
      if (m.code !== "not_found") this.error(`room ${m.room}: ${m.code}: ${m.message}`);
      return;
    }
    if (about && about.kind === "request" && !m.fatal) {
      // A request refused whole puts nothing in flight.
      for (const id of about.rooms || []) {
        const f = this.inFlight.get(id);
        if (f && f.ref === m.ref) this.inFlight.delete(id);
      }
      this.pausedUntil = this.now() + 1000;
      if (m.code !== "limit_exceeded") this.error(`request refused: ${m.code}: ${m.message}`);
      return;
    }
    if (m.retry_after_ms !== undefined) this.retryAfterMs = m.retry_after_ms;
    this.error(`server error ${m.code}${m.fatal ? " (fatal)" : ""}: ${m.message}`);
    if (m.code === "unauthorized" || m.code === "unsupported_version" || m.code === "world_mismatch") {
      this.lastFatal = m.code;
      this.lastFatalMessage = m.message;
    }
  }

  onBinary(data) {
    this.counts.frames++;
    const r = parseRoomFrame(data, { maxFrameBytes: this.limits?.max_frame_bytes ?? 4194304, version: this.version, maxLod: this.limits?.max_lod ?? 0 });
    if (!r.ok) {
      this.badFrame(null, `${r.code}: ${r.message}`);
      return;
    }
    const f = r.frame;
    const flight = this.inFlight.get(f.id);
    if (!flight) return; // cancelled while on the wire: dropped
    this.inFlight.delete(f.id);
    if (f.lod !== flight.lod) {
      this.badFrame(f.id, `bad_frame: room frame ${f.id}: lod ${f.lod}, asked for ${flight.lod}`);
      return;
    }
    this.hooks.onFrame?.(f);
  }

  // A refused frame: dropped whole, counted, shown; the room is asked again later.
  badFrame(id, text) {
    this.counts.badFrames++;
    this.error(`refused a room frame: ${text}`);
    if (id) this.failed.set(id, this.now() + 2000);
    else {
      // We do not know which room it was (its header was bad): everything in flight longer than
      // a few seconds is asked again by the planner's normal course once the server answers.
    }
  }

  // The viewer reports a room whose payload failed to decode (the worker's checks).
  payloadRefused(id, text) {
    this.badFrame(id, text);
  }

  onClose(code, reason) {
    this.stopTimers();
    const why = reason || this.lastFatal || "";
    const said = this.lastFatalMessage;
    this.lastFatal = this.lastFatalMessage = undefined;
    if (shouldStop(why)) {
      if (why === "unauthorized") {
        const token = this.hooks.needToken?.();
        if (token) {
          this.o.token = token;
          this.setStatus("reconnecting", "retrying with the token");
          this.counts.reconnects++;
          this.timers.push(setTimeout(() => this.connect(), 50));
          return;
        }
      }
      this.stopped = true;
      this.setStatus("stopped", refusalText(why, said));
      return;
    }
    this.scheduleReconnect({ code, reason });
  }

  scheduleReconnect(close) {
    if (this.stopped) return;
    const delay = reconnectDelay(this.attempt++, { ...close, retryAfterMs: this.retryAfterMs ?? 0 });
    this.retryAfterMs = 0;
    this.queued = null;
    const what = close.code ? `connection closed (${close.code}${close.reason ? " " + close.reason : ""})` : "connection lost";
    this.setStatus("reconnecting", `${what}: reconnecting in ${Math.round(delay)} ms`);
    this.timers.push(setTimeout(() => {
      this.counts.reconnects++;
      this.setStatus("connecting", "");
      this.connect();
    }, delay));
  }

  startTimers() {
    this.stopTimers();
    const idle = this.limits.idle_timeout_ms;
    const pingEvery = Math.max(50, Math.min(idle / 3, 20000));
    this.pingTimer = setInterval(() => {
      if (this.now() - this.lastSent >= pingEvery * 0.9) this.send(pingMessage(Date.now(), this.ref++));
    }, pingEvery);
    this.planTimer = setInterval(() => this.step(), 200);
  }

  stopTimers() {
    clearInterval(this.pingTimer);
    clearInterval(this.planTimer);
  }

  spawn() {
    this.send(spawnMessage(this.nextRef("spawn")));
  }

  locate(point) {
    this.pendingLocate = point;
    this.send(locateMessage(point, this.nextRef("locate")));
  }

  close() {
    this.stopped = true;
    this.stopTimers();
    for (const t of this.timers) clearTimeout(t);
    if (this.ws) this.ws.close(1000, "bye");
  }

  // One planning step: request what is within the horizon, cancel what fell out of it.
  step() {
    if (!this.welcomed || !this.ws || this.ws.readyState !== 1) return;
    const p = this.o.player();
    if (!p.room) return;
    const store = this.o.store;
    const now = this.now();
    const opts = { speed: p.speed || DEFAULTS.speed, horizonMs: DEFAULTS.horizonMs, cancelMs: DEFAULTS.cancelMs, maxRooms: store.maxRooms ?? DEFAULTS.maxRooms };
    const times = timesToReach(store.descriptors, p.room, p.position, p.forward, opts);
    this.lastTimes = times;
    const tokens = now < this.pausedUntil ? 0 : this.bucket.available(now);
    // A room in flight for long (its frame refused before its id could be read, or lost): cancel
    // it, so that it is asked again.
    const stale = [];
    for (const [id, f] of this.inFlight) if (now - f.sent > 30000) stale.push(id);
    if (stale.length && this.send(cancelMessage(stale.slice(0, this.limits.max_rooms_per_request), this.nextRef("cancel")))) {
      for (const id of stale.slice(0, this.limits.max_rooms_per_request)) this.inFlight.delete(id);
      this.counts.cancels += Math.min(stale.length, this.limits.max_rooms_per_request);
    }
    const out = plan({ loaded: store.loaded, inFlight: this.inFlight, failed: this.failed }, times, {
      maxRoomsInFlight: this.limits.max_rooms_in_flight,
      maxRoomsPerRequest: this.limits.max_rooms_per_request,
      tokens,
    }, now, opts);
    if (out.cancel.length) {
      if (this.send(cancelMessage(out.cancel, this.nextRef("cancel")))) {
        this.bucket.take(out.cancel.length, now);
        for (const id of out.cancel) this.inFlight.delete(id);
        this.counts.cancels += out.cancel.length;
      }
    }
    if (out.request.length) {
      const ref = this.nextRef("request", out.request.map((r) => r.id));
      if (this.send(requestMessage(out.request.map((r) => ({ id: r.id, lod: this.lod, priority: r.priority })), ref))) {
        this.bucket.take(out.request.length, now);
        for (const r of out.request) this.inFlight.set(r.id, { priority: r.priority, sent: now, lod: this.lod, ref });
        this.counts.requests += out.request.length;
      }
    }
    if (out.evict.length) this.hooks.onEvict?.(out.evict);
  }
}
