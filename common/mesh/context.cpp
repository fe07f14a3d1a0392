#include "common/mesh/context.hpp"

#include <cmath>
#include <cstdint>

#include "common/core/random.hpp"

namespace grotto::mesh {
namespace {

constexpr uint64_t kNoiseStream = 0x6e6f697365000001ull;  // "noise"

// v modulo the period in [0, period), a zero keeping v's sign: what fmod and one add of the
// period to a negative remainder give, bit for bit, without fmod or a floor call (a fifth of the
// detail channels' time). The period is a power of two, so q = v / period is exact, its floor
// (by truncation, exact below 2^62; beyond, q is already an integer) times the period is exact,
// and the one subtraction rounds the same exact value the add did.
static_assert(kNoisePeriod == 16384.0, "wrap() needs a power-of-two period");
double wrap(double v) {
  double q = v * (1.0 / kNoisePeriod);
  double f = q;
  if (std::abs(q) < 0x1p62) {
    f = static_cast<double>(static_cast<int64_t>(q));
    if (f > q) f -= 1.0;
  }
  double r = v - f * kNoisePeriod;
  return r == 0 ? std::copysign(0.0, v) : r;
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
