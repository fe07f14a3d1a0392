// The browser viewer's page: the session with grotto-server, the decode worker, the room store,
// the renderer, walk and fly, the overlay, place links, and window.grotto (the tests' view of the
// page: web/README in the lead's docs, and the playwright test).
import { Renderer, cameraForward } from "./render.js";
import { Session } from "./session.js";
import { Controls, EYE_HEIGHT } from "./controls.js";
import { RoomCollision, floorAt } from "./collision.js";
import { parsePose, formatPose, isSeed, printable } from "./protocol.js";

const q = new URLSearchParams(location.search);
const serverParam = q.get("server"); // host:port of another grotto-server (the page's own by default)
const host = serverParam || location.host;
const httpBase = serverParam ? `${location.protocol}//${serverParam}` : "";
const wsBase = serverParam ? `${location.protocol === "https:" ? "wss" : "ws"}://${serverParam}` : `${location.protocol === "https:" ? "wss" : "ws"}://${location.host}${location.pathname.replace(/[^/]*$/, "")}`;
const subdivision = Math.max(0, Math.min(2, Number(q.get("subdiv") ?? 1) | 0));
const wantExtras = q.get("extras") !== "0";
const MAX_ROOMS = Math.max(16, Number(q.get("rooms") ?? 400) | 0);

let token = q.get("token");
try {
  if (token) sessionStorage.setItem("grotto.token", token);
  else token = sessionStorage.getItem("grotto.token");
} catch {
  /* storage off */
}

const canvas = document.getElementById("view");
const overlay = document.getElementById("overlay");
const messageEl = document.getElementById("message");
const linkEl = document.getElementById("link");

const pose = { x: 0, y: 0, z: 0, yaw: 0, pitch: 0 };
const store = {
  rooms: new Map(), // id -> {frame, collision, rims, decode_ms}
  loaded: new Set(), // decoded, in the scene (and being decoded: not asked again)
  descriptors: new Map(), // id -> frame (centre, radius, portals): the portal graph
  maxRooms: MAX_ROOMS,
};
const decoding = new Map(); // worker job id -> frame
const errors = [];
const decodeMs = []; // per room: Draco, the payload's checks, the normals, the rims (last 256)
const subdivideMs = []; // per room: the subdivision for the vertex shader's relief (last 256)
let frames = 0;
let here = null; // the room the player is in
let placed = false; // the pose is known (spawn, link or setPose)
let aimAtSpawn = false;
let worldSeed = q.get("seed");
let worldParams = null;
let messageText = "";
let messageUntil = 0;
let lastLink = "";

function showMessage(text, sticky = false) {
  messageText = printable(text).slice(0, 600);
  messageEl.textContent = messageText;
  messageUntil = sticky ? Infinity : performance.now() + 10000;
}

function reportError(text) {
  const t = printable(text).slice(0, 600);
  errors.push(t);
  if (errors.length > 100) errors.splice(0, errors.length - 100);  // a long session's memory stays bounded
  if (errors.length > 256) errors.splice(0, errors.length - 256);
  showMessage(t);
}

if (worldSeed !== null && !isSeed(worldSeed)) {
  reportError(`seed '${worldSeed}' is not a decimal unsigned 64-bit number: using the server's world`);
  worldSeed = null;
}
const linkPose = parsePose(q.get("pose"));
if (q.get("pose") && !linkPose) reportError(`pose '${q.get("pose")}' is not x,y,z,yaw,pitch: starting at the spawn point`);

// ---- rendering ----
let renderer;
try {
  renderer = new Renderer(canvas);
  renderer.onError = (msg) => reportError(msg);
} catch (e) {
  reportError(`WebGL2 is not available: ${e.message}`);
}
function resize() {
  const w = Math.max(1, canvas.clientWidth | 0), h = Math.max(1, canvas.clientHeight | 0);
  if (renderer && (renderer.width !== w || renderer.height !== h)) renderer.resize(w, h);
}

// ---- decoding ----
const worker = new Worker(new URL("./decode_worker.js", import.meta.url));
let jobSeq = 1;
worker.onerror = (e) => reportError(`the decode worker failed: ${e.message || "error"}`);
worker.onmessage = (ev) => {
  const r = ev.data;
  const frame = decoding.get(r.id);
  decoding.delete(r.id);
  if (!frame) return;
  if (!r.ok) {
    store.loaded.delete(frame.id);
    if (r.code === "internal") reportError(r.message);
    else session.payloadRefused(frame.id, `${r.code}: room ${frame.id}: ${r.message}`);
    return;
  }
  if (!store.loaded.has(frame.id)) return; // evicted while decoding
  decodeMs.push(r.decode_ms);
  if (decodeMs.length > 256) decodeMs.splice(0, decodeMs.length - 256);
  subdivideMs.push(r.subdivide_ms);
  if (subdivideMs.length > 256) subdivideMs.splice(0, subdivideMs.length - 256);
  const room = {
    frame,
    rims: r.rims,
    decode_ms: r.decode_ms,
    collision: new RoomCollision(frame.origin, r.collision.positions, r.collision.indices),
  };
  store.rooms.set(frame.id, room);
  store.descriptors.set(frame.id, frame);
  if (renderer) renderer.addRoom(frame.id, frame, r);
  if (wantExtras && worldParams) fetchExtras(frame.id);
  if (aimAtSpawn && frame.id === here) aimThroughWidestPortal(frame);
};

function onFrame(frame) {
  if (store.loaded.has(frame.id)) return;
  store.loaded.add(frame.id);
  const id = jobSeq++;
  decoding.set(id, frame);
  const payload = frame.payload.slice(); // its own buffer, transferred
  const f = { origin: frame.origin, portals: frame.portals.map((p) => ({ centre: p.centre, normal: p.normal })), lod: frame.lod, version: frame.version };
  const light = { ...frame, payload: null };
  decoding.set(id, light);
  worker.postMessage({ id, payload: payload.buffer, frame: f, subdivision }, [payload.buffer]);
}

function evict(ids) {
  for (const id of ids) {
    if (id === here) continue;
    store.loaded.delete(id);
    store.rooms.delete(id);
    store.descriptors.delete(id);
    renderer?.removeRoom(id);
  }
}

async function fetchExtras(id) {
  const url = `${httpBase}/extras/v2/${worldSeed}/${worldParams}/${session.lod}/${id}`;
  try {
    const r = await fetch(url, { headers: token ? { Authorization: `Bearer ${token}` } : {} });
    if (r.status === 404) return; // a server without extras: bare rock, no lights
    if (!r.ok) {
      reportError(`extras for ${id}: HTTP ${r.status}`);
      return;
    }
    const extras = await r.json();
    if (store.rooms.has(id)) renderer?.setExtras(id, extras);
  } catch (e) {
    reportError(`extras for ${id}: ${e.message}`);
  }
}

// ---- where the player is ----
function roomsHolding(p) {
  const out = [];
  for (const [id, room] of store.rooms) {
    const f = room.frame;
    const d = Math.hypot(p[0] - f.centre[0], p[1] - f.centre[1], p[2] - f.centre[2]);
    if (d > f.radius + 1.5) continue;
    const inside = f.portals.every((pt) => (p[0] - pt.centre[0]) * pt.normal[0] + (p[1] - pt.centre[1]) * pt.normal[1] + (p[2] - pt.centre[2]) * pt.normal[2] <= 0.25);
    if (inside) out.push({ id, d });
  }
  out.sort((a, b) => a.d - b.d);
  return out.map((o) => o.id);
}

function aimThroughWidestPortal(frame) {
  aimAtSpawn = false;
  let best = null;
  for (const p of frame.portals) if (!best || p.radius > best.radius) best = p;
  if (!best) return;
  const d = [best.centre[0] - pose.x, best.centre[1] - pose.y, best.centre[2] - pose.z];
  pose.yaw = Math.atan2(d[0], -d[2]);
  pose.pitch = Math.max(-0.5, Math.min(0.5, Math.atan2(d[1], Math.hypot(d[0], d[2]))));
}

let locating = false;
function setPose(x, y, z, yaw = pose.yaw, pitch = pose.pitch) {
  const v = [x, y, z, yaw, pitch].map(Number);
  if (v.some((t) => !Number.isFinite(t))) throw new Error("setPose: every value must be a finite number");
  [pose.x, pose.y, pose.z, pose.yaw, pose.pitch] = v;
  controls.vy = 0;
  placed = true;
  const holding = roomsHolding([pose.x, pose.y, pose.z]);
  if (holding.length) here = holding[0];
  else if (session.welcomed) {
    locating = true;
    session.locate([pose.x, pose.y, pose.z]);
  } else pendingLocate = true;
}
let pendingLocate = false;

// ---- the session ----
const session = new Session({
  url: `${wsBase}${serverParam ? "/" : ""}ws${worldSeed ? `?seed=${worldSeed}` : ""}`,
  seed: worldSeed || undefined,
  token,
  lod: 0,
  store: {
    get loaded() {
      return store.loaded;
    },
    descriptors: store.descriptors,
    maxRooms: MAX_ROOMS,
  },
  player: () => ({
    room: here,
    position: [pose.x, pose.y, pose.z],
    forward: cameraForward(pose.yaw, pose.pitch),
    speed: controls.speed(),
  }),
  hooks: {
    onWelcome(m, first) {
      worldSeed = m.seed;
      worldParams = m.params;
      if (!first) return;
      if (linkPose && !placed) {
        setPose(linkPose.x, linkPose.y, linkPose.z, linkPose.yaw, linkPose.pitch);
      } else if (pendingLocate) {
        pendingLocate = false;
        session.locate([pose.x, pose.y, pose.z]);
        locating = true;
      } else if (!placed) session.spawn();
    },
    onSpawn(room, position) {
      if (placed) return;
      placed = true;
      here = room;
      [pose.x, pose.y, pose.z] = position;
      aimAtSpawn = true;
      const f = store.descriptors.get(room);
      if (f) aimThroughWidestPortal(f);
    },
    onLocated(room) {
      locating = false;
      if (room) here = room;
      else {
        reportError(`the place ${formatPose(pose)} is in rock or beyond the world: going to the spawn point`);
        placed = false;
        session.spawn();
      }
    },
    onFrame,
    onError: reportError,
    onEvict: evict,
    onWorldChanged() {
      evict([...store.loaded]);
      here = null;
      locating = true;
      session.locate([pose.x, pose.y, pose.z]);
    },
    onStatus(status, text) {
      if (status === "open" && session.counts.reconnects > 0) showMessage(`reconnected to ${host}`);
      if (text) showMessage(text, status === "stopped");
      else if (status === "open" && messageUntil !== Infinity) {
        /* keep the last message its while */
      }
    },
    needToken() {
      let t = null;
      try {
        t = window.prompt("This Grotto server needs a token:");
      } catch {
        t = null;
      }
      if (t) {
        token = t;
        try {
          sessionStorage.setItem("grotto.token", t);
        } catch {
          /* storage off */
        }
      }
      return t;
    },
  },
});

const controls = new Controls(canvas, pose, (x, top, z) => floorAt(store.rooms.values(), x, top, z));
controls.fly = q.get("fly") === "1";
// Flying keeps within the loaded rooms' spheres, short of their rims (the rock beyond is no place
// to be, and the native client's fly mode collides with it too).
controls.inside = (x, y, z) => roomsHolding([x, y, z]).length > 0;

function link() {
  const u = new URL(location.href);
  const keep = new URLSearchParams();
  keep.set("seed", worldSeed ?? "");
  keep.set("pose", formatPose(pose));
  if (controls.fly) keep.set("fly", "1");
  if (u.searchParams.get("server")) keep.set("server", u.searchParams.get("server"));
  return `${u.origin}${u.pathname}?${keep.toString().replace(/%2C/g, ",")}`;
}

controls.onKey = (code) => {
  if (code === "KeyL") {
    lastLink = link();
    linkEl.textContent = `link to this place: ${lastLink}`;
    try {
      navigator.clipboard?.writeText(lastLink).then(
        () => (linkEl.textContent = `copied: ${lastLink}`),
        () => {},
      );
    } catch {
      /* no clipboard here: the link stays on screen */
    }
  }
};

// ---- window.grotto: the tests' contract ----
function median(a) {
  if (!a.length) return 0;
  const s = [...a].sort((x, y) => x - y);
  return s[s.length >> 1];
}
window.grotto = {
  get rooms_loaded() {
    return renderer ? renderer.rooms.size : store.rooms.size;
  },
  get frames() {
    return frames;
  },
  get requests() {
    return session.counts.requests;
  },
  get cancels() {
    return session.counts.cancels;
  },
  errors,
  decode_ms: decodeMs,
  subdivide_ms: subdivideMs,
  get status() {
    return session.status;
  },
  get message() {
    return messageText;
  },
  get pose() {
    return { ...pose };
  },
  get seed() {
    return worldSeed;
  },
  get params() {
    return worldParams;
  },
  get room() {
    return here;
  },
  get reconnects() {
    return session.counts.reconnects;
  },
  get in_flight() {
    return session.inFlight.size;
  },
  get fly() {
    return controls.fly;
  },
  link,
  setPose,
  rim(roomId, slot) {
    const r = store.rooms.get(roomId);
    if (!r || !r.rims[slot]) return null;
    return r.rims[slot].map((p) => (p ? [p[0], p[1], p[2]] : null));
  },
  portals(roomId) {
    const r = store.rooms.get(roomId) || (store.descriptors.get(roomId) && { frame: store.descriptors.get(roomId) });
    if (!r) return null;
    return r.frame.portals.map((p) => ({ to: p.to, centre: [...p.centre], normal: [...p.normal], radius: p.radius }));
  },
  rooms() {
    return [...store.rooms.keys()];
  },
  get session() {
    return session;
  },
  // The lights each drawn room's rock and formations were last lit with (render.js: the lights
  // that reach the room, those whose haze its view rays cross, and which are next door), for the
  // rooms whose formations are built.
  lit() {
    if (!renderer) return [];
    const lists = (u) => ({
      count: u.u_light_count.value, index: [...u.u_light_index.value], next_door: [...u.u_light_next_door.value],
      haze_count: u.u_haze_count.value, haze_index: [...u.u_haze_index.value],
    });
    return [...renderer.rooms.entries()]
      .filter(([, r]) => r.formations && r.formations.visible && r.formations.children.length)
      .map(([id, r]) => ({ id, rock: lists(r.uniforms), formations: lists(r.formations.children[0].material.uniforms) }));
  },
};

// ---- the loop ----
let last = performance.now();
let fpsFrames = 0, fpsAt = last, fps = 0;
function tick(now) {
  const dt = (now - last) / 1000;
  last = now;
  if (placed) controls.update(dt);
  const holding = roomsHolding([pose.x, pose.y, pose.z]);
  if (holding.length) {
    if (!holding.includes(here)) here = holding[0];
  } else if (placed && here && store.rooms.has(here) && !locating && session.welcomed) {
    // Out of every loaded room (a jump, a pose in rooms not loaded yet): ask the server.
    const f = store.rooms.get(here).frame;
    if (Math.hypot(pose.x - f.centre[0], pose.y - f.centre[1], pose.z - f.centre[2]) > f.radius + 4) {
      locating = true;
      session.locate([pose.x, pose.y, pose.z]);
    }
  }
  resize();
  if (renderer) {
    try {
      renderer.render(pose);
    } catch (e) {
      reportError(`drawing failed: ${e.message}`);
    }
  }
  frames++;
  fpsFrames++;
  if (now - fpsAt >= 1000) {
    fps = (fpsFrames * 1000) / (now - fpsAt);
    fpsFrames = 0;
    fpsAt = now;
  }
  if (messageText && performance.now() > messageUntil) {
    messageText = "";
    messageEl.textContent = "";
  }
  requestAnimationFrame(tick);
}

function updateOverlay() {
  overlay.textContent = [
    `Grotto seed ${worldSeed ?? "?"}  server ${host}  ${session.status}`,
    `rooms ${window.grotto.rooms_loaded}  in flight ${session.inFlight.size}  requested ${session.counts.requests}  cancelled ${session.counts.cancels}`,
    `decode ${median(decodeMs).toFixed(2)} ms median  ${fps.toFixed(1)} fps  ${controls.fly ? "flying" : "walking"}`,
    `at ${pose.x.toFixed(1)}, ${pose.y.toFixed(1)}, ${pose.z.toFixed(1)}  room ${here ?? "-"}`,
  ].join("\n");
}
setInterval(updateOverlay, 250);

session.connect();
requestAnimationFrame(tick);
