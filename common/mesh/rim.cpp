#include "common/mesh/rim.hpp"

#include <algorithm>
#include <cmath>

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

RimLoop canonical_rim(const MeshContext& ctx, const cave::Room& room, const cave::Portal& portal,
                      Lod lod) {
  RimLoop loop = rim_frame(room, portal);
  const core::GrottoShape& shape = ctx.shape(lod);
  int k_count = rim_vertex_count(portal.radius, ctx.edge_length(lod));
  loop.positions.reserve(k_count);
  loop.normals.reserve(k_count);
  for (int k = 0; k < k_count; ++k) {
    double s, c;
    detmath::sincos(2.0 * detmath::kPi * k / k_count - detmath::kPi, s, c);
    Vec3 u = loop.e1 * c + loop.e2 * s;
    // Thesis §3.1.6: noise on the radius makes the rim irregular; sampled where the kernel samples
    // it (on the plain rim), from the canonical world position.
    core::float3 at = ctx.noise_position(portal.centre + u * portal.radius);
    float noise = core::grotto_noise3(ctx.noise_seed(), at, shape.rim_frequency);
    double radius = portal.radius * (1.0 + shape.rim_amplitude * static_cast<double>(noise));
    // The surface noise where the walls of both rooms reach the rim (deform_core.h), in the plane.
    core::float3 on_rim = ctx.noise_position(portal.centre + u * radius);
    float surface = core::grotto_surface_noise(ctx.noise_seed(), &shape, on_rim);
    radius += core::grotto_rim_noise(&shape, static_cast<float>(portal.radius), surface);
    loop.positions.push_back(grid::snap(portal.centre + u * radius));
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
  return portal_radius * (1.0 + params.rim_amplitude) + octaves + 0.5 * params.rim_softness;
}

}  // namespace grotto::mesh
