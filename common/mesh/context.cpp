#include "mesh/context.hpp"

#include <cmath>
#include <numeric>

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
  // Perlin's permutation, shuffled from the world seed (Fisher-Yates with our own Rng).
  std::array<unsigned char, 256> p;
  std::iota(p.begin(), p.end(), 0);
  Rng rng(hash_words(world.seed(), kNoiseStream));
  for (uint32_t i = 255; i > 0; --i)
    std::swap(p[i], p[rng.below(i + 1)]);
  for (int i = 0; i < 512; ++i)
    perm_[i] = p[i & 255];
  for (int l = 0; l < kLodCount; ++l)
    shapes_[l] = shape_for(params, static_cast<Lod>(l));
}

core::float3 MeshContext::noise_position(Vec3 w) const {
  return {static_cast<float>(wrap(w.x)), static_cast<float>(wrap(w.y)),
          static_cast<float>(wrap(w.z))};
}

}  // namespace grotto::mesh
