// Room payload decoding (proto/PROTOCOL.md, "Room payload (Draco)"): Draco through Google's
// decoder (draco3d's WebAssembly), the document's validation, version 2's normals derived in
// binary64, the rims' world positions, and one subdivision of every triangle for the vertex
// shader's relief (WebGL2 has no tessellation). A classic script with no imports: the decode worker
// loads it with importScripts, node's tests import it (it defines globalThis.GrottoDecode).
"use strict";

(function (root) {
  const LIMITS = [
    { maxBytes: 65536, maxVertices: 16384, maxTriangles: 32768 }, // lod 0
    { maxBytes: 262144, maxVertices: 65536, maxTriangles: 131072 }, // lod 1
  ];

  function DecodeError(message) {
    const e = new Error(message);
    e.code = "bad_frame";
    return e;
  }

  function limitsFor(lod) {
    return LIMITS[Math.min(lod, 1)];
  }

  // A Draco varint (7 bits a byte, low group first, at most 5 bytes). Returns [value, next] or null.
  function readVarint(bytes, at) {
    let value = 0;
    for (let i = 0; i < 5; ++i) {
      if (at >= bytes.length) return null;
      const b = bytes[at++];
      value += (b & 0x7f) * 2 ** (7 * i);
      if ((b & 0x80) === 0) return [value, at];
    }
    return null;
  }

  // The Draco header and connectivity counts, checked before Draco sees the bytes (Draco sizes its
  // tables from them). Throws DecodeError; returns {vertices, faces}.
  function checkHeader(bytes, lod) {
    const lim = limitsFor(lod);
    if (bytes.length > lim.maxBytes) throw DecodeError(`payload of ${bytes.length} bytes, over ${lim.maxBytes} at lod ${lod}`);
    if (bytes.length < 12) throw DecodeError("truncated Draco header");
    const magic = String.fromCharCode(bytes[0], bytes[1], bytes[2], bytes[3], bytes[4]);
    if (magic !== "DRACO") throw DecodeError("not a Draco payload (bad magic)");
    if (bytes[5] !== 2 || bytes[6] !== 2) throw DecodeError(`Draco bitstream version ${bytes[5]}.${bytes[6]}, expected 2.2`);
    if (bytes[7] !== 1) throw DecodeError("Draco payload is not a triangle mesh");
    if (bytes[8] !== 1) throw DecodeError("Draco payload is not edgebreaker");
    if (bytes[9] !== 0 || bytes[10] !== 0) throw DecodeError("unexpected Draco header flags (metadata)");
    if (bytes[11] > 2) throw DecodeError(`Draco traversal type ${bytes[11]}, expected 0-2`);
    let at = 12;
    const v = readVarint(bytes, at);
    if (!v) throw DecodeError("truncated Draco connectivity header");
    const f = readVarint(bytes, v[1]);
    if (!f) throw DecodeError("truncated Draco connectivity header");
    at = f[1];
    if (at >= bytes.length) throw DecodeError("truncated Draco connectivity header");
    const attributeData = bytes[at++];
    const s = readVarint(bytes, at);
    if (!s) throw DecodeError("truncated Draco connectivity header");
    const sp = readVarint(bytes, s[1]);
    if (!sp) throw DecodeError("truncated Draco connectivity header");
    const vertices = v[0], faces = f[0], splits = sp[0];
    if (faces > lim.maxTriangles) throw DecodeError(`declares ${faces} triangles, limit ${lim.maxTriangles}`);
    if (vertices + splits > lim.maxVertices) throw DecodeError(`declares ${vertices + splits} vertices, limit ${lim.maxVertices}`);
    if (attributeData > 3) throw DecodeError(`declares ${attributeData} attribute tables`);
    return { vertices, faces };
  }

  // Draco's decode and the attribute layout of version 2 (or 1): unique ids 0 (POSITION float32
  // x3), [1 (NORMAL float32 x3), version 1], 2 (GENERIC float32 x2), 3 (GENERIC uint16 x2). The
  // layout is checked before any value is copied out of Draco.
  function dracoDecode(M, bytes, lod, version) {
    const lim = limitsFor(lod);
    const decoder = new M.Decoder();
    const mesh = new M.Mesh();
    const ptrs = [];
    try {
      const status = decoder.DecodeArrayToMesh(new Int8Array(bytes.buffer, bytes.byteOffset, bytes.byteLength), bytes.byteLength, mesh);
      if (!status.ok() || mesh.ptr === 0) throw DecodeError("Draco: " + status.error_msg());
      const n = mesh.num_points();
      const t = mesh.num_faces();
      if (n < 3 || n > lim.maxVertices) throw DecodeError(`${n} vertices, outside 3..${lim.maxVertices}`);
      if (t < 1 || t > lim.maxTriangles) throw DecodeError(`${t} triangles, outside 1..${lim.maxTriangles}`);
      const expected = version === 1 ? 4 : 3;
      if (mesh.num_attributes() !== expected) throw DecodeError(`${mesh.num_attributes()} attributes, expected ${expected}`);
      const want = [
        { uid: 0, type: M.POSITION, dt: M.DT_FLOAT32, comps: 3, name: "position" },
        { uid: 2, type: M.GENERIC, dt: M.DT_FLOAT32, comps: 2, name: "channels" },
        { uid: 3, type: M.GENERIC, dt: M.DT_UINT16, comps: 2, name: "rim" },
      ];
      if (version === 1) want.splice(1, 0, { uid: 1, type: M.NORMAL, dt: M.DT_FLOAT32, comps: 3, name: "normal" });
      const attrs = {};
      for (const w of want) {
        const a = decoder.GetAttributeByUniqueId(mesh, w.uid);
        if (!a || a.ptr === 0) throw DecodeError(`missing attribute: ${w.name}`);
        if (a.attribute_type() !== w.type || a.data_type() !== w.dt || a.num_components() !== w.comps || a.normalized())
          throw DecodeError(`attribute ${w.name} has the wrong type or component count`);
        attrs[w.name] = a;
      }
      const copy = (a, comps, dt, Heap, Arr) => {
        const count = n * comps;
        const bytesLen = count * Arr.BYTES_PER_ELEMENT;
        const ptr = M._malloc(bytesLen);
        ptrs.push(ptr);
        const ok = decoder.GetAttributeDataArrayForAllPoints(mesh, a, dt, bytesLen, ptr);
        if (!ok) throw DecodeError("Draco: could not read an attribute");
        const heap = M[Heap];
        return new Arr(heap.buffer, ptr, count).slice();
      };
      const positions = copy(attrs.position, 3, M.DT_FLOAT32, "HEAPF32", Float32Array);
      const channels = copy(attrs.channels, 2, M.DT_FLOAT32, "HEAPF32", Float32Array);
      const rim = copy(attrs.rim, 2, M.DT_UINT16, "HEAPU16", Uint16Array);
      const sentNormals = version === 1 ? copy(attrs.normal, 3, M.DT_FLOAT32, "HEAPF32", Float32Array) : null;
      const ibytes = t * 3 * 4;
      const iptr = M._malloc(ibytes);
      ptrs.push(iptr);
      decoder.GetTrianglesUInt32Array(mesh, ibytes, iptr);
      const indices = new Uint32Array(M.HEAPU32.buffer, iptr, t * 3).slice();
      return { positions, channels, rim, indices, sentNormals, n, t };
    } finally {
      for (const p of ptrs) M._free(p);
      M.destroy(mesh);
      M.destroy(decoder);
    }
  }

  // The rest of PROTOCOL's validation list on the decoded values.
  function validate(d, origin, portalCount) {
    const { positions, channels, rim, indices, sentNormals, n } = d;
    for (let v = 0; v < n; ++v) {
      for (let k = 0; k < 3; ++k) {
        const x = positions[3 * v + k];
        if (!Number.isFinite(x) || Math.abs(x) > 1024) throw DecodeError(`vertex ${v}: position not finite or beyond the room's frame`);
      }
      if (sentNormals) {
        const l = Math.hypot(sentNormals[3 * v], sentNormals[3 * v + 1], sentNormals[3 * v + 2]);
        if (!(Math.abs(l - 1) <= 1e-3)) throw DecodeError(`vertex ${v}: normal is not unit length`);
      }
      for (let k = 0; k < 2; ++k) {
        const c = channels[2 * v + k];
        if (!(c >= 0 && c <= 1)) throw DecodeError(`vertex ${v}: channel outside [0, 1]`);
      }
      const s = rim[2 * v], k = rim[2 * v + 1];
      if (s !== 0 && s - 1 >= portalCount) throw DecodeError(`vertex ${v}: rim slot ${s - 1} out of range`);
      if (s === 0 && k !== 0) throw DecodeError(`vertex ${v}: rim index off any rim`);
      if (s !== 0) {
        for (let a = 0; a < 3; ++a) {
          const w = origin[a] + positions[3 * v + a];
          if (!Number.isInteger(w * 256)) throw DecodeError(`vertex ${v}: rim vertex is not on the 1/256 m grid`);
        }
      }
    }
    for (let f = 0; f < indices.length / 3; ++f) {
      const a = indices[3 * f], b = indices[3 * f + 1], c = indices[3 * f + 2];
      if (a >= n || b >= n || c >= n) throw DecodeError(`triangle ${f}: index out of range`);
      if (a === b || b === c || a === c) throw DecodeError(`triangle ${f} is degenerate`);
    }
  }

  // PROTOCOL "Normals" (version 2), as grotto::codec::derive_normals computes them: in binary64,
  // the rim rule for rim vertices, the area-weighted sum of cross(b - a, c - a) otherwise, rounded
  // to float32 at the end. portals: [{centre, normal}] in frame order.
  function deriveNormals(positions, indices, rim, origin, portals) {
    const n = positions.length / 3;
    const sum = new Float64Array(3 * n);
    for (let i = 0; i + 2 < indices.length; i += 3) {
      const a = indices[i], b = indices[i + 1], c = indices[i + 2];
      const ax = positions[3 * a], ay = positions[3 * a + 1], az = positions[3 * a + 2];
      const ux = positions[3 * b] - ax, uy = positions[3 * b + 1] - ay, uz = positions[3 * b + 2] - az;
      const wx = positions[3 * c] - ax, wy = positions[3 * c + 1] - ay, wz = positions[3 * c + 2] - az;
      const fx = uy * wz - uz * wy, fy = uz * wx - ux * wz, fz = ux * wy - uy * wx;
      for (const v of [a, b, c]) {
        sum[3 * v] += fx;
        sum[3 * v + 1] += fy;
        sum[3 * v + 2] += fz;
      }
    }
    const out = new Float32Array(3 * n);
    for (let v = 0; v < n; ++v) {
      let dx = sum[3 * v], dy = sum[3 * v + 1], dz = sum[3 * v + 2];
      const slot = rim[2 * v] - 1;
      if (slot >= 0) {
        const r = rimRadial(origin, positions[3 * v], positions[3 * v + 1], positions[3 * v + 2], portals[slot]);
        if (r[0] * r[0] + r[1] * r[1] + r[2] * r[2] > 0) {
          dx = -r[0];
          dy = -r[1];
          dz = -r[2];
        }
      }
      const len = Math.sqrt(dx * dx + dy * dy + dz * dz);
      if (len > 0) {
        out[3 * v] = dx / len;
        out[3 * v + 1] = dy / len;
        out[3 * v + 2] = dz / len;
      } else {
        out[3 * v] = 0;
        out[3 * v + 1] = 1;
        out[3 * v + 2] = 0;
      }
    }
    return out;
  }

  // d = (origin + p) - c; r = d - n (d . n): d's part in the portal's plane.
  function rimRadial(origin, px, py, pz, portal) {
    const c = portal.centre, nn = portal.normal;
    const dx = origin[0] + px - c[0], dy = origin[1] + py - c[1], dz = origin[2] + pz - c[2];
    const dot = dx * nn[0] + dy * nn[1] + dz * nn[2];
    return [dx - nn[0] * dot, dy - nn[1] * dot, dz - nn[2] * dot];
  }

  // The world positions (binary64: origin + float32 offset) of every rim vertex, by portal slot and
  // loop index: {slot: [[x, y, z] at k]}.
  function rimPositions(positions, rim, origin) {
    const out = {};
    for (let v = 0; v < positions.length / 3; ++v) {
      const s = rim[2 * v];
      if (s === 0) continue;
      const slot = s - 1, k = rim[2 * v + 1];
      (out[slot] = out[slot] || [])[k] = [origin[0] + positions[3 * v], origin[1] + positions[3 * v + 1], origin[2] + positions[3 * v + 2]];
    }
    return out;
  }

  function before(ax, ay, az, bx, by, bz) {
    if (ax !== bx) return ax < bx;
    if (ay !== by) return ay < by;
    return az < bz;
  }

  // One subdivision: each triangle into four, through its edges' midpoints, each edge's midpoint
  // made once and shared by the two triangles on it (no cracks), and computed from the edge's two
  // endpoints alone in a canonical order (the lexicographically smaller world position first), so
  // the rooms on both sides of a portal make the same point of a rim edge. The midpoint lies on the
  // edge's cubic PN curve (Vlachos et al. 2001: what room.tese's PN triangles give at w = 1/2) in
  // binary64 world coordinates; normals, roughness, mineral and rim weight are averaged (a rim
  // edge keeps rim weight 1, so the relief leaves it where the server put it).
  // mesh: {positions (Float32 offsets), normals, roughness, mineral, rimWeight, indices}.
  function subdivide(mesh, origin, curved = true) {
    const n = mesh.positions.length / 3;
    const tri = mesh.indices.length / 3;
    const edges = new Map();
    let count = n;
    const keyOf = (a, b) => (a < b ? a * 65536 * 4 + b : b * 65536 * 4 + a);
    for (let i = 0; i < mesh.indices.length; i += 3) {
      for (let e = 0; e < 3; ++e) {
        const a = mesh.indices[i + e], b = mesh.indices[i + ((e + 1) % 3)];
        const key = keyOf(a, b);
        if (!edges.has(key)) edges.set(key, count++);
      }
    }
    const P = new Float32Array(3 * count), N = new Float32Array(3 * count);
    const R = new Float32Array(count), Mn = new Float32Array(count), W = new Float32Array(count);
    P.set(mesh.positions);
    N.set(mesh.normals);
    R.set(mesh.roughness);
    Mn.set(mesh.mineral);
    W.set(mesh.rimWeight);
    const p = mesh.positions, nn = mesh.normals;
    for (const [key, m] of edges) {
      let a = Math.floor(key / (65536 * 4)), b = key - a * 65536 * 4;
      const wa = [origin[0] + p[3 * a], origin[1] + p[3 * a + 1], origin[2] + p[3 * a + 2]];
      const wb = [origin[0] + p[3 * b], origin[1] + p[3 * b + 1], origin[2] + p[3 * b + 2]];
      let A = wa, B = wb;
      if (before(wb[0], wb[1], wb[2], wa[0], wa[1], wa[2])) {
        const t = a; a = b; b = t;
        A = wb; B = wa;
      }
      const na = [nn[3 * a], nn[3 * a + 1], nn[3 * a + 2]], nb = [nn[3 * b], nn[3 * b + 1], nn[3 * b + 2]];
      let mid;
      if (curved) {
        // cab = (2A + B - ((B - A) . na) na) / 3, cba likewise; mid = (A + B) / 8 + 3 (cab + cba) / 8.
        const dab = (B[0] - A[0]) * na[0] + (B[1] - A[1]) * na[1] + (B[2] - A[2]) * na[2];
        const dba = (A[0] - B[0]) * nb[0] + (A[1] - B[1]) * nb[1] + (A[2] - B[2]) * nb[2];
        mid = [0, 1, 2].map((k) => {
          const cab = (2 * A[k] + B[k] - dab * na[k]) / 3;
          const cba = (2 * B[k] + A[k] - dba * nb[k]) / 3;
          return (A[k] + B[k]) * 0.125 + (cab + cba) * 0.375;
        });
      } else {
        mid = [0.5 * (A[0] + B[0]), 0.5 * (A[1] + B[1]), 0.5 * (A[2] + B[2])];
      }
      P[3 * m] = mid[0] - origin[0];
      P[3 * m + 1] = mid[1] - origin[1];
      P[3 * m + 2] = mid[2] - origin[2];
      const sx = na[0] + nb[0], sy = na[1] + nb[1], sz = na[2] + nb[2];
      const l = Math.sqrt(sx * sx + sy * sy + sz * sz);
      if (l > 0) {
        N[3 * m] = sx / l;
        N[3 * m + 1] = sy / l;
        N[3 * m + 2] = sz / l;
      } else {
        N[3 * m] = na[0];
        N[3 * m + 1] = na[1];
        N[3 * m + 2] = na[2];
      }
      R[m] = 0.5 * (mesh.roughness[a] + mesh.roughness[b]);
      Mn[m] = 0.5 * (mesh.mineral[a] + mesh.mineral[b]);
      W[m] = 0.5 * (mesh.rimWeight[a] + mesh.rimWeight[b]);
    }
    const I = new Uint32Array(tri * 12);
    for (let f = 0; f < tri; ++f) {
      const a = mesh.indices[3 * f], b = mesh.indices[3 * f + 1], c = mesh.indices[3 * f + 2];
      const ab = edges.get(keyOf(a, b)), bc = edges.get(keyOf(b, c)), ca = edges.get(keyOf(c, a));
      I.set([a, ab, ca, ab, b, bc, ca, bc, c, ab, bc, ca], 12 * f);
    }
    return { positions: P, normals: N, roughness: R, mineral: Mn, rimWeight: W, indices: I };
  }

  // The median edge length of a mesh (metres): the step the relief is sampled at (room.tese's
  // u_patch_edge).
  function medianEdge(positions, indices) {
    const lens = [];
    for (let i = 0; i < indices.length; i += 3) {
      for (let e = 0; e < 3; ++e) {
        const a = indices[i + e], b = indices[i + ((e + 1) % 3)];
        if (a < b) lens.push(Math.hypot(positions[3 * a] - positions[3 * b], positions[3 * a + 1] - positions[3 * b + 1], positions[3 * a + 2] - positions[3 * b + 2]));
      }
    }
    if (!lens.length) return 0;
    lens.sort((x, y) => x - y);
    return lens[lens.length >> 1];
  }

  // The whole decode of one frame's payload. frame: {origin, portals, lod, version}. Returns the
  // room's arrays (subdivided for drawing, the patch mesh for collision) or throws a DecodeError.
  function decodeRoom(M, payload, frame, { subdivision = 1, curved = true } = {}) {
    const t0 = performance.now();
    const bytes = payload instanceof Uint8Array ? payload : new Uint8Array(payload);
    checkHeader(bytes, frame.lod);
    const d = dracoDecode(M, bytes, frame.lod, frame.version);
    validate(d, frame.origin, frame.portals.length);
    const normals = d.sentNormals || deriveNormals(d.positions, d.indices, d.rim, frame.origin, frame.portals);
    const roughness = new Float32Array(d.n), mineral = new Float32Array(d.n), rimWeight = new Float32Array(d.n);
    for (let v = 0; v < d.n; ++v) {
      roughness[v] = d.channels[2 * v];
      mineral[v] = d.channels[2 * v + 1];
      rimWeight[v] = d.rim[2 * v] !== 0 ? 1 : 0;
    }
    let mesh = { positions: d.positions, normals, roughness, mineral, rimWeight, indices: d.indices };
    const rims = rimPositions(d.positions, d.rim, frame.origin);
    // The decode (Draco, the checks, the normals, the rims) apart from the drawing's preparation.
    const t1 = performance.now();
    const baseEdge = medianEdge(d.positions, d.indices);
    for (let i = 0; i < subdivision; ++i) mesh = subdivide(mesh, frame.origin, curved);
    return {
      decode_ms: t1 - t0,
      subdivide_ms: performance.now() - t1,
      draw: mesh,
      collision: { positions: d.positions, indices: d.indices },
      rims,
      normals,
      rim: d.rim,
      vertices: d.n,
      triangles: d.t,
      spacing: baseEdge / 2 ** subdivision,
    };
  }

  root.GrottoDecode = { LIMITS, checkHeader, dracoDecode, validate, deriveNormals, rimRadial, rimPositions, subdivide, medianEdge, decodeRoom, readVarint };
})(typeof self !== "undefined" ? self : globalThis);
