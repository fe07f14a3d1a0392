#include "common/mesh/rim.hpp"

#include <algorithm>
#include <cmath>

#include "common/cave/geology.hpp"
#include "common/core/detmath.hpp"
#include "common/core/grid.hpp"

namespace grotto::mesh {

int rim_vertex_count(double radius, double edge_length) {
  return std::max(8, static_cast<int>(std::ceil(2.0 * detmath::kPi * radius / edge_length)));
}

RimLoop rim_frame(const cave::Room& room, const cave::Portal& portal) {
  RimLoop loop;
  loop.centre = portal.centre;
  // Both rooms see the same disc, with opposite normals: orient it from the lower id.
  loop.normal = room.id < portal.neighbour ? portal.normal : -portal.normal;
  // The basis starts from the world axis least aligned with the normal (first on ties).
  Vec3 n = loop.normal;
  double ax = std::abs(n.x), ay = std::abs(n.y), az = std::abs(n.z);
  Vec3 helper = ax <= ay && ax <= az ? Vec3{1, 0, 0} : (ay <= az ? Vec3{0, 1, 0} : Vec3{0, 0, 1});
  loop.e1 = normalize(cross(helper, n));
  loop.e2 = cross(n, loop.e1);
  return loop;
}

core::GrottoPortal portal_record(const MeshContext& ctx, const cave::Room& room,
                                 const cave::Portal& portal, Vec3 origin) {
  RimLoop basis = rim_frame(room, portal);
  core::GrottoPortal g{};
  Vec3 c = portal.centre - origin;
  g.cx = static_cast<float>(c.x);
  g.cy = static_cast<float>(c.y);
  g.cz = static_cast<float>(c.z);
  g.nx = static_cast<float>(portal.normal.x);
  g.ny = static_cast<float>(portal.normal.y);
  g.nz = static_cast<float>(portal.normal.z);
  g.e1x = static_cast<float>(basis.e1.x);
  g.e1y = static_cast<float>(basis.e1.y);
  g.e1z = static_cast<float>(basis.e1.z);
  g.e2x = static_cast<float>(basis.e2.x);
  g.e2y = static_cast<float>(basis.e2.y);
  g.e2z = static_cast<float>(basis.e2.z);
  g.radius = static_cast<float>(portal.radius);
  // The section from the canonical normal, its height in the canonical basis: both rooms agree.
  cave::PassageSection section =
      cave::passage_section(ctx.world(), portal.centre, basis.normal, portal.radius);
  g.up_c = static_cast<float>(dot(section.up, basis.e1));
  g.up_s = static_cast<float>(dot(section.up, basis.e2));
  g.half_w = static_cast<float>(section.half_width);
  g.half_h = static_cast<float>(section.half_height);
  g.slot_depth = static_cast<float>(section.slot_depth);
  g.slot_width = static_cast<float>(section.slot_width);
  g.reach = static_cast<float>(cave::section_reach(section));
  g.narrow = static_cast<float>(cave::section_narrow(section));
  return g;
}

RimLoop canonical_rim(const MeshContext& ctx, const cave::Room& room, const cave::Portal& portal,
                      Lod lod) {
  RimLoop loop = rim_frame(room, portal);
  const core::GrottoShape& shape = ctx.shape(lod);
  // The record in the portal's own frame: only its section is read here.
  const core::GrottoPortal record = portal_record(ctx, room, portal, portal.centre);
  const cave::PassageSection section =
      cave::passage_section(ctx.world(), portal.centre, loop.normal, portal.radius);
  // As many vertices as the disc's circle at least: a slot's corners and floor need them.
  int k_count = rim_vertex_count(portal.radius * std::max(1.0, cave::section_perimeter(section)),
                                 ctx.edge_length(lod));
  loop.positions.reserve(k_count);
  loop.normals.reserve(k_count);
  for (int k = 0; k < k_count; ++k) {
    double s, c;
    detmath::sincos(2.0 * detmath::kPi * k / k_count - detmath::kPi, s, c);
    Vec3 u = loop.e1 * c + loop.e2 * s;
    // Thesis §3.1.6: noise on the radius makes the rim irregular; sampled where the kernel samples
    // it (on the plain rim), from the canonical world position. The passage's section shapes it
    // (deform_core.h: the same function the kernel evaluates).
    core::float3 at = ctx.noise_position(portal.centre + u * portal.radius);
    float noise = core::grotto_noise3(ctx.noise_seed(), at, shape.rim_frequency);
    core::float3 uf{static_cast<float>(u.x), static_cast<float>(u.y), static_cast<float>(u.z)};
    double radius = portal.radius * (1.0 + shape.rim_amplitude * static_cast<double>(noise)) *
                    static_cast<double>(core::grotto_section(&record, uf));
    // The surface noise where the walls of both rooms reach the rim (deform_core.h), in the plane.
    core::float3 on_rim = ctx.noise_position(portal.centre + u * radius);
    float surface = core::grotto_surface_noise(ctx.noise_seed(), &shape, on_rim);
    radius += core::grotto_rim_noise(&shape, record.radius * record.narrow, surface);
    loop.positions.push_back(grid::snap(portal.centre + u * radius));
    // The normal is level with the portal disc, towards its axis (-u): the rule PROTOCOL.md
    // gives receivers that derive normals, so that both rooms and every client agree. (Square to
    // a section's outline it looked a little better at a slot's corners, but a client could not
    // derive it from the frame.)
    loop.normals.push_back(
        {static_cast<float>(-u.x), static_cast<float>(-u.y), static_cast<float>(-u.z)});
  }
  return loop;
}

double rim_reach(const MeshParams& params, double portal_radius) {
  double octaves = 0;
  for (const LodParams& lod : params.lods) {
    double sum = 0;
    for (int k = 0; k < lod.octaves; ++k)
      sum += params.octave_amplitude[k];
    octaves = std::max(octaves, sum);
  }
  return portal_radius * cave::kMaxSectionReach * (1.0 + params.rim_amplitude) + octaves +
         0.5 * params.rim_softness;
}

}  // namespace grotto::mesh
