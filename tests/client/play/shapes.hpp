// Hand-made collision rooms for play_tests: floors, walls, ledges and ramps as quads, so the
// player's exact resting heights and stopping points can be asserted.
#pragma once

#include <vector>

#include "client/stream/room_store.hpp"
#include "common/cave/layout.hpp"
#include "common/core/vec3.hpp"

namespace grotto::play::test {

struct Quad {
  Vec3 a, b, c, d;  // corners in order
};

// A room `index` of sector (0,0,0) holding the quads as its patch mesh, its sphere around them,
// its vertices as offsets from `origin` (as a decoded room holds them).
inline stream::ReadyRoom shape_room(int index, const std::vector<Quad>& quads, Vec3 origin = {},
                                    std::vector<cave::Portal> portals = {}) {
  stream::ReadyRoom r;
  r.room.id = cave::RoomId::interior({0, 0, 0}, index);
  r.room.sphere = {origin, 100};
  r.room.portals = std::move(portals);
  r.origin = origin;
  // Each quad's face normal at its corners: a flat quad stays flat as a PN patch.
  auto vertex = [&](Vec3 p, Vec3 n) {
    r.mesh.positions.push_back(
        {static_cast<float>(p.x), static_cast<float>(p.y), static_cast<float>(p.z)});
    r.mesh.normals.push_back(
        {static_cast<float>(n.x), static_cast<float>(n.y), static_cast<float>(n.z)});
    r.mesh.roughness.push_back(0);
    r.mesh.mineral.push_back(0);
    r.mesh.rim_portal.push_back(-1);
    r.mesh.rim_index.push_back(0);
    return static_cast<uint32_t>(r.mesh.positions.size() - 1);
  };
  for (const Quad& q : quads) {
    const Vec3 e1 = q.b - q.a, e2 = q.c - q.a;
    Vec3 n{e1.y * e2.z - e1.z * e2.y, e1.z * e2.x - e1.x * e2.z, e1.x * e2.y - e1.y * e2.x};
    n = n / length(n);
    const uint32_t a = vertex(q.a, n), b = vertex(q.b, n), c = vertex(q.c, n), d = vertex(q.d, n);
    r.mesh.indices.insert(r.mesh.indices.end(), {a, b, c, a, c, d});
  }
  return r;
}

// A horizontal square of half-size h at height y around (x, z).
inline Quad floor_quad(double y, double h = 50, double x = 0, double z = 0) {
  return {{x - h, y, z - h}, {x - h, y, z + h}, {x + h, y, z + h}, {x + h, y, z - h}};
}

// A wall in the plane x = x0, from y0 to y1 and z in [-h, h].
inline Quad wall_x(double x0, double y0 = -1, double y1 = 10, double h = 50) {
  return {{x0, y0, -h}, {x0, y1, -h}, {x0, y1, h}, {x0, y0, h}};
}

}  // namespace grotto::play::test
