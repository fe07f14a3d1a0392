// Donor spheres (thesis §3.1.3): geodesic spheres whose resolution follows the room's radius, so
// that edges are about the same length in big and small rooms.
#pragma once

#include <cstdint>
#include <memory>
#include <vector>

#include "common/mesh/deform.hpp"

namespace grotto::mesh {

struct DonorSphere {
  int frequency = 0;                     // icosahedron edges split into this many segments
  std::vector<core::float3> directions;  // unit vectors
  std::vector<uint32_t> indices;         // triangles, counter-clockwise seen from outside
  // neighbours[3t + k]: the triangle across edge (indices[3t + k], indices[3t + (k + 1) % 3]).
  std::vector<uint32_t> neighbours;
  // corner[v]: a corner 3t + k of a triangle at vertex v (indices[3t + k] == v).
  std::vector<uint32_t> corner;
  // The vertices that share an edge with v: adjacent[adjacent_start[v] .. adjacent_start[v + 1]).
  std::vector<uint32_t> adjacent_start, adjacent;
};

// The frequency that gives edges of about `edge_length` on a sphere of `radius`.
int donor_frequency(double radius, double edge_length);

// Cached and shared: donors depend only on the frequency. Thread-safe.
std::shared_ptr<const DonorSphere> donor_sphere(int frequency);

}  // namespace grotto::mesh
