#include "mesh/context.hpp"

#include <cmath>

#include "core/random.hpp"

namespace grotto::mesh {
namespace {

constexpr uint64_t kNoiseStream = 0x6e6f697365000001ull;  // "noise"

double wrap(double v) {
  double r = std::fmod(v, kNoisePeriod);
  return r < 0 ? r + kNoisePeriod : r;
}

}  // namespace

Result<MeshContext> MeshContext::create(const cave::World& world, const MeshParams& params) {
  if (Status s = validate(params); !s) return s.error();
  return MeshContext(world, params);
}

MeshContext::MeshContext(const cave::World& world, const MeshParams& params)
    : world_(world), params_(params) {
  noise_seed_ = static_cast<uint32_t>(hash_words(world.seed(), kNoiseStream) >> 32);
  for (int l = 0; l < kLodCount; ++l)
    shapes_[l] = shape_for(params, static_cast<Lod>(l));
}

core::float3 MeshContext::noise_position(Vec3 w) const {
  return {static_cast<float>(wrap(w.x)), static_cast<float>(wrap(w.y)),
          static_cast<float>(wrap(w.z))};
}

}  // namespace grotto::mesh
