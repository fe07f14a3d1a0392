// The viewer's renderer: three.js (WebGL2) drawing each room with the native client's own shaders
// (generated into shaders.js by web/tools/shaders.mjs: room.frag, formation.vert, relief.glsl,
// lights.glsl, and the web room vertex stage that applies the relief per vertex). What
// client/render/renderer.cpp does, in the subset a browser needs: the anchor scheme (positions
// relative to a 1024 m block corner near the camera, u_block its integer block), the headlamp, the
// world's lights (the 16 nearest, packed as renderer.cpp packs them, each room shaded only by the
// lights that reach it), fog into the dark, ACES tone mapping in room.frag, formations as
// instances drawn with formation.vert and room.frag.
import * as THREE from "three";
import { roomVert, roomFrag, formationVert } from "./shaders.js";
import { knownFormations, FORMATION_DRAPERY as DRAPERY } from "./protocol.js";

export const ANCHOR_STEP = 1024; // = relief.glsl's kReliefBlock
export const MAX_LIGHTS = 16;

// RenderOptions' defaults (client/render/renderer.hpp).
export const OPTIONS = {
  fovY: (70 * Math.PI) / 180,
  near: 0.05,
  far: 96,
  fogStart: 24,
  fogEnd: 64,
  lampRange: 14,
  haze: 0.03,
  fineDetail: 1,
  ao: 1,
  exposure: 1,
  glow: 1,
  displacement: 1,
  fogColor: [0.01, 0.011, 0.013],
  // formations.hpp's kLodSides[1] x kLodRings[1]: one level of detail for every instance but the
  // draperies, which take kLodSides[0] x kLodRings[0]: their sides run down the sheet's faces
  // (8 points down a face, not 5) and there are few of them.
  formationSides: 10,
  formationRings: 16,
  draperySides: 16,
  draperyRings: 32,
};

const GLOW = { glow_worms: 0, seam: 1, crystals: 2, flare: 3 };

// renderer.cpp's camera_forward: yaw 0 looks down -z, pitch up positive.
export function cameraForward(yaw, pitch) {
  const p = Math.max(-1.5533, Math.min(1.5533, pitch));
  return [Math.sin(yaw) * Math.cos(p), Math.sin(p), -Math.cos(yaw) * Math.cos(p)];
}

export function renderAnchor(p) {
  return p.map((x) => Math.floor(x / ANCHOR_STEP) * ANCHOR_STEP);
}

function stripVersion(src) {
  // three adds `#version 300 es` itself for GLSL3 materials.
  return src.replace(/^#version 300 es\s*\n/, "");
}

// The (s, theta) grid of one formation instance's mesh (formation.vert): `rings` along it,
// `sides` round it.
function makeFormationGrid(sides, rings) {
  const grid = [];
  for (let i = 0; i <= rings; ++i) for (let k = 0; k <= sides; ++k) grid.push(i / rings, (2 * Math.PI * k) / sides);
  const idx = [];
  const row = sides + 1;
  for (let i = 0; i < rings; ++i)
    for (let k = 0; k < sides; ++k) {
      const a0 = i * row + k, a1 = a0 + 1, b0 = a0 + row, b1 = b0 + 1;
      idx.push(a0, b0, b1, a0, b1, a1);
    }
  return { grid: new Float32Array(grid), index: new Uint16Array(idx) };
}

function len3(a, b) {
  return Math.hypot(a[0] - b[0], a[1] - b[1], a[2] - b[2]);
}

export class Renderer {
  constructor(canvas, options = {}) {
    this.o = { ...OPTIONS, ...options };
    THREE.ColorManagement.enabled = false;
    this.three = new THREE.WebGLRenderer({ canvas, antialias: false, powerPreference: "high-performance", preserveDrawingBuffer: true });
    this.three.setPixelRatio(1);
    this.three.outputColorSpace = THREE.LinearSRGBColorSpace;
    this.three.toneMapping = THREE.NoToneMapping;
    this.three.setClearColor(new THREE.Color(...this.o.fogColor), 1);
    this.three.sortObjects = true;
    this.scene = new THREE.Scene();
    this.camera = new THREE.PerspectiveCamera((this.o.fovY * 180) / Math.PI, 16 / 9, this.o.near, this.o.far);
    this.rooms = new Map(); // id -> {mesh, formations, frame, extras, origin}
    this.anchor = null;
    // Uniforms every program reads, shared (one {value} each) by every material.
    const f = (v) => ({ value: v });
    this.frame = {
      u_view_proj: f(new THREE.Matrix4()),
      u_camera: f(new THREE.Vector3()),
      u_block: f([0, 0, 0]),
      u_displacement: f(this.o.displacement),
      u_fog_color: f(new THREE.Vector3(...this.o.fogColor)),
      u_fog_start: f(this.o.fogStart),
      u_fog_end: f(this.o.fogEnd),
      u_lamp_range: f(this.o.lampRange),
      u_fine_detail: f(this.o.fineDetail),
      u_ao: f(this.o.ao),
      u_pixel_scale: f(1),
      u_exposure: f(this.o.exposure),
      u_glow: f(this.o.glow),
      u_lamp: f(new THREE.Vector3()),
      u_forward: f(new THREE.Vector3(0, 0, -1)),
      u_headlamp: f(1),
      u_haze: f(this.o.haze),
      u_light_position: f(new Float32Array(4 * MAX_LIGHTS)),
      u_light_color: f(new Float32Array(4 * MAX_LIGHTS)),
      u_light_glow: f(new Float32Array(4 * MAX_LIGHTS)),
      u_light_bound: f(new Float32Array(4 * MAX_LIGHTS)),
    };
    this.points = []; // this frame's lights (world coordinates)
    this.formationGrid = makeFormationGrid(this.o.formationSides, this.o.formationRings);
    this.draperyGrid = makeFormationGrid(this.o.draperySides, this.o.draperyRings);
    this.shaderErrors = [];
    this.three.debug.onShaderError = (gl, program, vs, fs) => {
      const log = (s) => gl.getShaderInfoLog(s) || "";
      const msg = `shader compile failed: ${gl.getProgramInfoLog(program)} ${log(vs)} ${log(fs)}`.slice(0, 2000);
      this.shaderErrors.push(msg);
      if (this.onError) this.onError(msg);
    };
  }

  roomUniforms() {
    return {
      ...this.frame,
      u_room_offset: { value: new THREE.Vector3() },
      u_patch_edge: { value: 0 },
      u_light_count: { value: 0 },
      u_light_index: { value: new Int32Array(MAX_LIGHTS) },
      u_haze_count: { value: 0 },
      u_haze_index: { value: new Int32Array(MAX_LIGHTS) },
      u_light_next_door: { value: new Float32Array(MAX_LIGHTS) },
    };
  }

  material(vert, uniforms) {
    return new THREE.RawShaderMaterial({
      glslVersion: THREE.GLSL3,
      vertexShader: stripVersion(vert),
      fragmentShader: stripVersion(roomFrag),
      uniforms,
      side: THREE.DoubleSide, // rooms are seen from inside; a thin wall may show its back
    });
  }

  // frame: the parsed room frame (origin, centre, radius, portals); decoded: the worker's result.
  addRoom(id, frame, decoded) {
    this.removeRoom(id);
    const d = decoded.draw;
    const g = new THREE.BufferGeometry();
    g.setAttribute("a_position", new THREE.BufferAttribute(d.positions, 3));
    g.setAttribute("a_normal", new THREE.BufferAttribute(d.normals, 3));
    g.setAttribute("a_roughness", new THREE.BufferAttribute(d.roughness, 1));
    g.setAttribute("a_mineral", new THREE.BufferAttribute(d.mineral, 1));
    g.setAttribute("a_rim", new THREE.BufferAttribute(d.rimWeight, 1));
    g.setIndex(new THREE.BufferAttribute(d.indices, 1));
    const c = frame.centre, o = frame.origin;
    // Every vertex lies within the sphere (plus the relief and a margin).
    g.boundingSphere = new THREE.Sphere(new THREE.Vector3(c[0] - o[0], c[1] - o[1], c[2] - o[2]), frame.radius + 2.5);
    const uniforms = this.roomUniforms();
    uniforms.u_patch_edge.value = decoded.spacing;
    const mesh = new THREE.Mesh(g, this.material(roomVert, uniforms));
    mesh.matrixAutoUpdate = true;
    const room = { id, mesh, uniforms, frame, origin: o, formations: null, formationData: null, lights: [], anchorKey: null };
    this.rooms.set(id, room);
    this.scene.add(mesh);
    return room;
  }

  // extras: the server's /extras resource for the room (lights, formations), or null.
  setExtras(id, extras) {
    const room = this.rooms.get(id);
    if (!room || !extras) return;
    room.lights = (extras.lights || []).map((l) => ({
      position: l.position, colour: l.colour, range: l.range, size: l.size,
      source_radius: l.source_radius, glow: typeof l.glow === "number" ? l.glow : GLOW[l.kind] ?? 0,
      seed: l.seed ?? 0, bound_centre: l.bound_centre || l.position, bound_radius: l.bound_radius ?? 0, kind: l.kind,
    }));
    const data = knownFormations(extras.formations);
    if (data) {
      room.formationData = data;
      room.anchorKey = null; // rebuilt at the next frame
    }
  }

  // A room's formations as instances, anchor-relative: the draperies on their own finer grid, the
  // rest on the shared one; one group, one set of uniforms (its lights the room's).
  buildFormations(room, anchor) {
    this.dropFormations(room);
    if (!room.formationData) return;
    const all = room.formationData;
    const off = [0, 1, 2].map((k) => Math.fround(room.origin[k] - anchor[k])); // exact: grid values
    const parts = [[], []]; // instance numbers: other kinds, draperies
    for (let i = 0; i < all.length / 16; ++i) parts[all[16 * i + 7] === DRAPERY ? 1 : 0].push(i);
    const uniforms = this.roomUniforms();
    // Lit as the room's rock is: the same lists of lights (render fills them room by room), so
    // its formations get the haze before them and the spill from a lit room next door.
    for (const k of ["u_light_count", "u_light_index", "u_haze_count", "u_haze_index", "u_light_next_door"])
      uniforms[k] = room.uniforms[k];
    const group = new THREE.Group();
    parts.forEach((ids, p) => {
      if (ids.length === 0) return;
      const data = new Float32Array(16 * ids.length);
      ids.forEach((i, j) => {
        data.set(all.subarray(16 * i, 16 * i + 16), 16 * j);
        for (let k = 0; k < 3; ++k) data[16 * j + k] = Math.fround(data[16 * j + k] + off[k]);
      });
      const grid = p === 1 ? this.draperyGrid : this.formationGrid;
      const g = new THREE.InstancedBufferGeometry();
      g.setAttribute("a_grid", new THREE.BufferAttribute(grid.grid, 2));
      g.setIndex(new THREE.BufferAttribute(grid.index, 1));
      const buf = new THREE.InstancedInterleavedBuffer(data, 16, 1);
      g.setAttribute("i_root", new THREE.InterleavedBufferAttribute(buf, 4, 0));
      g.setAttribute("i_size", new THREE.InterleavedBufferAttribute(buf, 4, 4));
      g.setAttribute("i_form", new THREE.InterleavedBufferAttribute(buf, 4, 8));
      g.setAttribute("i_turn", new THREE.InterleavedBufferAttribute(buf, 4, 12));
      g.instanceCount = ids.length;
      const mesh = new THREE.Mesh(g, this.material(formationVert, uniforms));
      mesh.frustumCulled = false;
      group.add(mesh);
    });
    room.formations = group;
    this.scene.add(group);
  }

  dropFormations(room) {
    if (!room.formations) return;
    this.scene.remove(room.formations);
    for (const mesh of room.formations.children) {
      mesh.geometry.dispose();
      mesh.material.dispose();
    }
    room.formations = null;
  }

  removeRoom(id) {
    const room = this.rooms.get(id);
    if (!room) return;
    this.scene.remove(room.mesh);
    room.mesh.geometry.dispose();
    room.mesh.material.dispose();
    this.dropFormations(room);
    this.rooms.delete(id);
  }

  resize(width, height) {
    this.three.setSize(width, height, false);
    this.camera.aspect = width / Math.max(1, height);
    this.camera.updateProjectionMatrix();
    this.width = width;
    this.height = height;
  }

  // pose: {x, y, z, yaw, pitch} (world, binary64).
  render(pose) {
    const o = this.o;
    const position = [pose.x, pose.y, pose.z];
    const anchor = renderAnchor(position);
    const anchorKey = anchor.join(",");
    const eye = position.map((x, k) => x - anchor[k]);
    const forward = cameraForward(pose.yaw, pose.pitch);
    const cam = this.camera;
    cam.position.set(eye[0], eye[1], eye[2]);
    cam.up.set(0, 1, 0);
    cam.lookAt(eye[0] + forward[0], eye[1] + forward[1], eye[2] + forward[2]);
    cam.updateMatrixWorld(true);
    const fr = this.frame;
    fr.u_view_proj.value.multiplyMatrices(cam.projectionMatrix, cam.matrixWorldInverse);
    fr.u_camera.value.set(eye[0], eye[1], eye[2]);
    fr.u_block.value = anchor.map((a) => Math.round(a / ANCHOR_STEP));
    fr.u_forward.value.set(forward[0], forward[1], forward[2]);
    fr.u_pixel_scale.value = (this.height || 720) / (2 * Math.tan(o.fovY / 2));
    // The headlamp: on the forehead, a little right of the eye (renderer.cpp's frame_lights).
    let right = [forward[1] * 0 - forward[2] * 1, forward[2] * 0 - forward[0] * 0, forward[0] * 1 - forward[1] * 0];
    const rl = Math.hypot(...right);
    right = rl > 1e-9 ? right.map((x) => x / rl) : [Math.cos(pose.yaw), 0, Math.sin(pose.yaw)];
    fr.u_lamp.value.set(eye[0] + right[0] * 0.25, eye[1] + 0.3, eye[2] + right[2] * 0.25);

    // The world's lights: those whose range reaches rock nearer than the fog's end, nearest first,
    // 16 at most, packed as renderer.cpp packs them.
    const picks = [];
    for (const [id, room] of this.rooms)
      for (const l of room.lights) {
        const d = len3(l.position, position);
        if (d >= l.range + o.fogEnd) continue;
        if (l.bound_radius > 0 && len3(l.bound_centre, position) >= l.bound_radius + o.fogEnd) continue;
        picks.push({ d, l, id });
      }
    picks.sort((a, b) => a.d - b.d);
    const points = picks.slice(0, MAX_LIGHTS).map((p) => p.l);
    const pointRooms = picks.slice(0, MAX_LIGHTS).map((p) => p.id);
    this.points = points;
    const P = fr.u_light_position.value, C = fr.u_light_color.value, G = fr.u_light_glow.value, B = fr.u_light_bound.value;
    P.fill(0); C.fill(0); G.fill(0); B.fill(0);
    points.forEach((l, n) => {
      P.set([l.position[0] - anchor[0], l.position[1] - anchor[1], l.position[2] - anchor[2], Math.max(l.range, 1e-3)], 4 * n);
      C.set([l.colour[0], l.colour[1], l.colour[2], 0], 4 * n);
      G.set([l.size, l.glow, l.seed, Math.max(l.source_radius, 0.05)], 4 * n);
      B.set([l.bound_centre[0] - anchor[0], l.bound_centre[1] - anchor[1], l.bound_centre[2] - anchor[2], Math.max(l.bound_radius, 0)], 4 * n);
    });
    fr.u_haze.value = points.length ? o.haze : 0;

    // Rooms: anchor-relative offsets, the lights that reach each, nearest first, fog-culled.
    const margin = 0.30 * 1.35 * 1.2 + 0.14 + 0.22 + 0.5; // relief_bound(1) + PN bulges
    const order = [];
    for (const room of this.rooms.values()) {
      const f = room.frame;
      const dist = Math.max(len3(f.centre, position) - f.radius, 0);
      const visible = dist < o.fogEnd + margin;
      room.mesh.visible = visible;
      const off = [0, 1, 2].map((k) => room.origin[k] - anchor[k]);
      room.mesh.position.set(off[0], off[1], off[2]);
      room.uniforms.u_room_offset.value.set(off[0], off[1], off[2]);
      if (room.anchorKey !== anchorKey) {
        room.anchorKey = anchorKey;
        this.buildFormations(room, anchor);
      }
      if (room.formations) room.formations.visible = visible;
      if (!visible) continue;
      order.push({ room, dist });
      const reach = f.radius + 2.5 + margin;
      let shade = 0, haze = 0;
      const si = room.uniforms.u_light_index.value, hi = room.uniforms.u_haze_index.value;
      const nd = room.uniforms.u_light_next_door.value;
      si.fill(0); hi.fill(0); nd.fill(0);
      points.forEach((l, i) => {
        const bounded = l.bound_radius > 0;
        const shades = len3(l.position, f.centre) < l.range + reach && (!bounded || len3(l.bound_centre, f.centre) < l.bound_radius + reach);
        const hazes = !bounded || len3(l.bound_centre, position) < l.bound_radius;
        // Through a portal of the light's room: its light reaches the first metres in (lights.glsl's
        // kLightSpill).
        if (shades) {
          nd[shade] = f.portals.some((p) => p.to === pointRooms[i]) ? 1 : 0;
          si[shade++] = i;
        }
        if (shades || hazes) hi[haze++] = i;
      });
      room.uniforms.u_light_count.value = shade;
      room.uniforms.u_haze_count.value = haze;
    }
    order.sort((a, b) => a.dist - b.dist);
    order.forEach(({ room }, i) => {
      room.mesh.renderOrder = i;
      if (room.formations) for (const mesh of room.formations.children) mesh.renderOrder = order.length + i;
    });
    this.anchor = anchor;
    this.three.render(this.scene, cam);
  }
}
