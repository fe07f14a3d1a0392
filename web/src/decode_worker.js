// The decode worker (a classic worker): Google's Draco decoder (draco3d's WebAssembly, served by
// grotto-server at /viewer/lib/) and decode_core.js's checks, normals and subdivision, off the
// main thread. Messages in: {id, payload (ArrayBuffer), frame: {origin, portals, lod, version},
// subdivision}; out: {id, ok: true, room arrays (transferred), rims, decode_ms} or {id, ok: false,
// code, message}.
/* global importScripts, DracoDecoderModule, GrottoDecode */
"use strict";

importScripts("lib/draco_decoder.js", "decode_core.js");

let ready = null;

function start() {
  if (!ready) {
    ready = fetch(new URL("lib/draco_decoder.wasm", self.location.href))
      .then((r) => {
        if (!r.ok) throw new Error(`draco_decoder.wasm: HTTP ${r.status}`);
        return r.arrayBuffer();
      })
      .then((wasmBinary) => DracoDecoderModule({ wasmBinary }));
  }
  return ready;
}

start();

self.onmessage = async (event) => {
  const { id, payload, frame, subdivision, curved } = event.data;
  let M;
  try {
    M = await start();
  } catch (e) {
    self.postMessage({ id, ok: false, code: "internal", message: `the Draco decoder did not load: ${e.message}` });
    return;
  }
  const t0 = performance.now();
  try {
    const room = GrottoDecode.decodeRoom(M, new Uint8Array(payload), frame, { subdivision: subdivision ?? 1, curved: curved ?? true });
    const { decode_ms, subdivide_ms } = room;
    const d = room.draw;
    const transfer = [...new Set([d.positions.buffer, d.normals.buffer, d.roughness.buffer, d.mineral.buffer, d.rimWeight.buffer, d.indices.buffer,
      room.collision.positions.buffer, room.collision.indices.buffer])];
    self.postMessage({
      id, ok: true, decode_ms, subdivide_ms,
      draw: d, collision: room.collision, rims: room.rims, spacing: room.spacing,
      vertices: room.vertices, triangles: room.triangles,
    }, transfer);
  } catch (e) {
    self.postMessage({ id, ok: false, code: e.code || "bad_frame", message: String(e.message || e), decode_ms: performance.now() - t0 });
  }
};
