// What every room mesh of a world shares: the validated parameters, the noise seed drawn
// from the world seed, and the device-facing shape of each level of detail.
#pragma once

#include <array>
#include <cstdint>

#include "common/cave/layout.hpp"
#include "common/core/result.hpp"
#include "common/mesh/params.hpp"

namespace grotto::mesh {

// Noise is evaluated at world positions reduced modulo this period (metres), so float32 keeps
// millimetre precision anywhere in the unbounded world.
inline constexpr double kNoisePeriod = 16384.0;

class MeshContext {
 public:
  static Result<MeshContext> create(const cave::World& world, const MeshParams& params);

  const cave::World& world() const { return world_; }
  const MeshParams& params() const { return params_; }
  uint32_t noise_seed() const { return noise_seed_; }  // the noise lattice hash's seed
  const core::GrottoShape& shape(Lod lod) const { return shapes_[static_cast<int>(lod)]; }
  double edge_length(Lod lod) const { return params_.lods[static_cast<int>(lod)].edge_length; }

  // A world position in noise space, as the float the core samples.
  core::float3 noise_position(Vec3 world) const;

 private:
  MeshContext(const cave::World& world, const MeshParams& params);
  cave::World world_;
  MeshParams params_;
  uint32_t noise_seed_ = 0;
  std::array<core::GrottoShape, kLodCount> shapes_{};
};

}  // namespace grotto::mesh
