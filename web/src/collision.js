// Floors under the player: a vertical ray down through the loaded rooms' patch meshes (as the
// server sent them, before the relief: within ~0.5 m of the drawn rock). Each room's triangles
// are binned once into a 2 m grid over x and z. Only upward-facing triangles are floors.

const CELL = 2.0;

export class RoomCollision {
  // positions: Float32Array offsets from origin; indices: Uint32Array.
  constructor(origin, positions, indices) {
    this.origin = origin;
    this.positions = positions;
    this.indices = indices;
    let minX = Infinity, minZ = Infinity, maxX = -Infinity, maxZ = -Infinity;
    for (let i = 0; i < positions.length; i += 3) {
      minX = Math.min(minX, positions[i]);
      maxX = Math.max(maxX, positions[i]);
      minZ = Math.min(minZ, positions[i + 2]);
      maxZ = Math.max(maxZ, positions[i + 2]);
    }
    this.minX = minX;
    this.minZ = minZ;
    this.nx = Math.max(1, Math.ceil((maxX - minX) / CELL) + 1);
    this.nz = Math.max(1, Math.ceil((maxZ - minZ) / CELL) + 1);
    this.maxX = maxX;
    this.maxZ = maxZ;
    const cells = new Array(this.nx * this.nz);
    const P = positions;
    for (let t = 0; t < indices.length; t += 3) {
      const a = 3 * indices[t], b = 3 * indices[t + 1], c = 3 * indices[t + 2];
      // Upward-facing only: cross(b - a, c - a).y > 0 (triangles are CCW seen from inside).
      const ux = P[b] - P[a], uz = P[b + 2] - P[a + 2], wx = P[c] - P[a], wz = P[c + 2] - P[a + 2];
      const ny = uz * wx - ux * wz;
      if (!(ny > 0)) continue;
      const x0 = Math.floor((Math.min(P[a], P[b], P[c]) - minX) / CELL), x1 = Math.floor((Math.max(P[a], P[b], P[c]) - minX) / CELL);
      const z0 = Math.floor((Math.min(P[a + 2], P[b + 2], P[c + 2]) - minZ) / CELL), z1 = Math.floor((Math.max(P[a + 2], P[b + 2], P[c + 2]) - minZ) / CELL);
      for (let i = x0; i <= x1; ++i) for (let k = z0; k <= z1; ++k) (cells[i * this.nz + k] ||= []).push(t);
    }
    this.cells = cells;
  }

  // The highest floor at world (x, z) at or below height top, or null.
  floor(x, top, z) {
    const lx = x - this.origin[0], lz = z - this.origin[2], ltop = top - this.origin[1];
    if (lx < this.minX || lx > this.maxX || lz < this.minZ || lz > this.maxZ) return null;
    const i = Math.floor((lx - this.minX) / CELL), k = Math.floor((lz - this.minZ) / CELL);
    const list = this.cells[i * this.nz + k];
    if (!list) return null;
    const P = this.positions, I = this.indices;
    let best = null;
    for (const t of list) {
      const a = 3 * I[t], b = 3 * I[t + 1], c = 3 * I[t + 2];
      const ax = P[a], az = P[a + 2], bx = P[b], bz = P[b + 2], cx = P[c], cz = P[c + 2];
      const d = (bz - cz) * (ax - cx) + (cx - bx) * (az - cz);
      if (d === 0) continue;
      const u = ((bz - cz) * (lx - cx) + (cx - bx) * (lz - cz)) / d;
      const v = ((cz - az) * (lx - cx) + (ax - cx) * (lz - cz)) / d;
      const w = 1 - u - v;
      if (u < -1e-6 || v < -1e-6 || w < -1e-6) continue;
      const y = u * P[a + 1] + v * P[b + 1] + w * P[c + 1];
      if (y <= ltop && (best === null || y > best)) best = y;
    }
    return best === null ? null : best + this.origin[1];
  }
}

// rooms: iterable of {collision: RoomCollision, frame: {centre, radius}}.
export function floorAt(rooms, x, top, z) {
  let best = null;
  for (const r of rooms) {
    if (!r.collision) continue;
    const c = r.frame.centre;
    if (Math.hypot(x - c[0], z - c[2]) > r.frame.radius + 3) continue;
    const y = r.collision.floor(x, top, z);
    if (y !== null && (best === null || y > best)) best = y;
  }
  return best;
}
