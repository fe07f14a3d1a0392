// The noise field every stage samples (deform_core.h): deterministic, seeded, and seamless across
// the wrap of world positions at the noise period.
#include <gtest/gtest.h>

#include <cmath>

#include "common/mesh/context.hpp"
#include "common/mesh/deform.hpp"

namespace grotto::mesh {
namespace {

// Every frequency MeshParams uses by default, as the core samples it (float).
std::vector<float> default_frequencies() {
  MeshParams p;
  std::vector<float> f(p.octave_frequency.begin(), p.octave_frequency.end());
  for (double v : {p.rim_frequency, p.big_frequency, p.roughness_frequency,
                   3 * p.roughness_frequency, p.mineral_frequency}) {
    f.push_back(static_cast<float>(v));
  }
  return f;
}

TEST(Noise, repeats_over_the_noise_period_at_every_default_frequency) {
  // A portal near the wrap is sampled unwrapped by the kernel (room origin + offset) and wrapped
  // by the canonical rim; both must see the same field, up to float rounding.
  const float period = static_cast<float>(kNoisePeriod);
  for (float f : default_frequencies()) {
    float worst = 0;
    for (int i = 0; i < 200; ++i) {
      float x = 0.37f * static_cast<float>(i) - 3.0f, y = 1.7f + 0.11f * i, z = 5.0f - 0.23f * i;
      float a = core::grotto_noise3(7u, core::float3{x, y, z}, f);
      float b = core::grotto_noise3(7u, core::float3{x + period, y, z - period}, f);
      worst = std::max(worst, std::fabs(a - b));
    }
    EXPECT_LT(worst, 0.02f) << "frequency " << f;
  }
}

TEST(Noise, frequencies_off_the_wrap_step_are_refused_by_name) {
  MeshParams p;
  p.rim_frequency = 0.35;  // 16,384 * 0.35 cells is not a whole number of lattice periods
  Status s = validate(p);
  ASSERT_FALSE(s.ok());
  EXPECT_NE(s.error().message.find("rim_frequency"), std::string::npos) << s.error().message;
  EXPECT_NE(s.error().message.find("1/64"), std::string::npos) << s.error().message;
  p = MeshParams{};
  p.octave_frequency[2] = 0.6;
  ASSERT_FALSE(validate(p).ok());
  p = MeshParams{};
  EXPECT_TRUE(validate(p).ok());
}

TEST(Noise, depends_on_the_seed_and_stays_in_range) {
  int differ = 0;
  for (int i = 0; i < 1000; ++i) {
    core::float3 at{0.731f * i, 0.173f * i + 0.5f, 1000.0f - 0.377f * i};
    float a = core::grotto_noise3(1u, at, 0.3f), b = core::grotto_noise3(2u, at, 0.3f);
    EXPECT_LE(std::fabs(a), 1.5f);
    differ += a != b;
  }
  EXPECT_GT(differ, 900);
}

}  // namespace
}  // namespace grotto::mesh
