// The CPU's SIMD lanes (mesh/deform_lanes.hpp) against the scalar reference: every lane gives the
// reference's bits, so the meshes do not depend on which path built them.
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <limits>
#include <vector>

#include "common/mesh/deform_lanes.hpp"
#include "common/mesh/room_mesh.hpp"

namespace grotto::mesh {
namespace {

uint32_t bits(float f) {
  uint32_t b;
  std::memcpy(&b, &f, sizeof b);
  return b;
}

TEST(Lanes, floor_is_std_floor_bit_for_bit) {
  const float inf = std::numeric_limits<float>::infinity();
  std::vector<float> xs = {0.0f,
                           -0.0f,
                           0.5f,
                           -0.5f,
                           1.0f,
                           -1.0f,
                           1e-30f,
                           -1e-30f,
                           1e-45f,
                           -1e-45f,
                           2.5f,
                           -2.5f,
                           8388607.5f,
                           -8388607.5f,
                           8388608.0f,
                           -8388608.0f,
                           8388609.0f,
                           -8388609.0f,
                           1e20f,
                           -1e20f,
                           inf,
                           -inf,
                           16383.999f,
                           -16383.999f,
                           255.99998f,
                           std::nextafter(1.0f, 0.0f),
                           -std::nextafter(1.0f, 0.0f)};
  while (xs.size() % core::lanes::kLanes != 0)
    xs.push_back(0.25f);
  for (size_t i = 0; i < xs.size(); i += core::lanes::kLanes) {
    core::lanes::gfloat v;
    for (int k = 0; k < core::lanes::kLanes; ++k)
      v[k] = xs[i + k];
    core::lanes::gfloat f = core::lanes::grotto_floor(v);
    for (int k = 0; k < core::lanes::kLanes; ++k) {
      EXPECT_EQ(bits(f[k]), bits(std::floor(xs[i + k]))) << "floor(" << xs[i + k] << ")";
    }
  }
  core::lanes::gfloat nan = core::lanes::splat(std::numeric_limits<float>::quiet_NaN());
  EXPECT_TRUE(std::isnan(core::lanes::grotto_floor(nan)[0]));
}

class LanesTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    world_ = new cave::World(cave::World::create(42, cave::LayoutParams{}).value());
    ctx_ = new MeshContext(MeshContext::create(*world_, MeshParams{}).value());
    region_ = new cave::Region(cave::generate_region(*world_, {-1, 0, 0}, {0, 0, 0}));
  }
  static void TearDownTestSuite() {
    delete region_;
    delete ctx_;
    delete world_;
  }
  static cave::World* world_;
  static MeshContext* ctx_;
  static cave::Region* region_;
};
cave::World* LanesTest::world_ = nullptr;
MeshContext* LanesTest::ctx_ = nullptr;
cave::Region* LanesTest::region_ = nullptr;

TEST_F(LanesTest, deformation_in_lanes_is_the_scalar_reference_bit_for_bit) {
  size_t vertices = 0;
  for (Lod lod : {Lod::kDetail, Lod::kPatch}) {
    for (const cave::Room& room : region_->rooms) {
      DeformInput in = prepare_room(*ctx_, room, lod);
      const size_t n = in.donor->directions.size();
      std::vector<core::float3> p(n), p_ref(n);
      std::vector<float> c(n), c_ref(n);
      deform_cpu(*ctx_, in, p, c);
      deform_reference(*ctx_, in, p_ref, c_ref);
      ASSERT_EQ(std::memcmp(p.data(), p_ref.data(), n * sizeof(core::float3)), 0)
          << room.id.to_string();
      ASSERT_EQ(std::memcmp(c.data(), c_ref.data(), n * sizeof(float)), 0) << room.id.to_string();
      vertices += n;
    }
  }
  EXPECT_GT(vertices, 100000u);
}

TEST_F(LanesTest, detail_channels_in_lanes_are_the_scalar_reference_bit_for_bit) {
  // Deformed rooms on both sides of x = 0 (negative world coordinates wrap differently), plus
  // points at and beside the noise period's multiples, where the wrap's zero keeps its sign.
  std::vector<std::pair<Vec3, std::vector<core::float3>>> sets;
  for (const cave::Room& room : region_->rooms) {
    DeformInput in = prepare_room(*ctx_, room, Lod::kPatch);
    std::vector<core::float3> p(in.donor->directions.size());
    std::vector<float> c(p.size());
    deform_cpu(*ctx_, in, p, c);
    sets.push_back({in.origin, std::move(p)});
  }
  std::vector<core::float3> edge;
  for (float d : {0.0f, -0.0f, 1e-7f, -1e-7f, 0.5f, -0.5f, 3.0f})
    edge.push_back({d, -d, d});
  for (double o : {0.0, kNoisePeriod, -kNoisePeriod, -2 * kNoisePeriod, 3 * kNoisePeriod + 0.25})
    sets.push_back({Vec3{o, -o, o}, edge});
  for (const auto& [origin, positions] : sets) {
    const size_t n = positions.size();
    std::vector<float> r(n), m(n), r_ref(n), m_ref(n);
    detail_channels(*ctx_, origin, positions, r, m);
    detail_channels_reference(*ctx_, origin, positions, r_ref, m_ref);
    ASSERT_EQ(std::memcmp(r.data(), r_ref.data(), n * sizeof(float)), 0);
    ASSERT_EQ(std::memcmp(m.data(), m_ref.data(), n * sizeof(float)), 0);
  }
}

TEST(NoisePosition, wraps_as_fmod_does_bit_for_bit) {
  auto world = cave::World::create(1, cave::LayoutParams{}).value();
  auto ctx = MeshContext::create(world, MeshParams{}).value();
  auto fmod_wrap = [](double v) {
    double r = std::fmod(v, kNoisePeriod);
    return static_cast<float>(r < 0 ? r + kNoisePeriod : r);
  };
  for (double v : {0.0,
                   -0.0,
                   1.0,
                   -1.0,
                   1e-20,
                   -1e-20,
                   kNoisePeriod,
                   -kNoisePeriod,
                   2 * kNoisePeriod,
                   -2 * kNoisePeriod,
                   kNoisePeriod - 1e-9,
                   -kNoisePeriod + 1e-9,
                   123456.789,
                   -123456.789,
                   1e15 + 0.5,
                   -1e15 - 0.5,
                   1e300,
                   -1e300,
                   std::nextafter(-kNoisePeriod, 0.0),
                   std::nextafter(kNoisePeriod, 0.0)}) {
    core::float3 w = ctx.noise_position({v, v, v});
    EXPECT_EQ(bits(w.x), bits(fmod_wrap(v))) << v;
  }
}

}  // namespace
}  // namespace grotto::mesh
