// The generated rock materials (pure: no GL): deterministic, tileable, varied, and three
// different layers with unit normals.
#include <gtest/gtest.h>

#include <cmath>

#include "client/render/materials.hpp"

namespace grotto::render {
namespace {

constexpr int kSize = 64;

// Channel `c` of texel (x, y) of `layer` in an RGBA8 image set, in [0, 1].
double at(const std::vector<uint8_t>& texels, int layer, int x, int y, int c) {
  const size_t i = (static_cast<size_t>(layer) * kSize * kSize + static_cast<size_t>(y) * kSize +
                    static_cast<size_t>(x)) *
                       4 +
                   static_cast<size_t>(c);
  return texels[i] / 255.0;
}

double layer_mean(const std::vector<uint8_t>& texels, int layer, int c) {
  double sum = 0;
  for (int y = 0; y < kSize; ++y)
    for (int x = 0; x < kSize; ++x)
      sum += at(texels, layer, x, y, c);
  return sum / (kSize * kSize);
}

TEST(Materials, the_same_size_gives_the_same_texels_and_bad_sizes_give_none) {
  const MaterialImages a = generate_materials(kSize), b = generate_materials(kSize);
  EXPECT_EQ(a.size, kSize);
  EXPECT_EQ(a.albedo.size(), static_cast<size_t>(kSize * kSize * kMaterialLayers * 4));
  EXPECT_EQ(a.albedo, b.albedo);
  EXPECT_EQ(a.normal, b.normal);
  for (int bad : {0, 8, 100, 4096, -64})
    EXPECT_EQ(generate_materials(bad).size, 0) << bad;
}

// Across the wrap (last column to first, last row to first) heights change no more than between
// neighbours inside the image: a texture that does not tile shows a seam there.
TEST(Materials, every_layer_tiles_without_a_seam) {
  const MaterialImages m = generate_materials(kSize);
  for (int layer = 0; layer < kMaterialLayers; ++layer) {
    double seam_x = 0, seam_y = 0, inner_x = 0, inner_y = 0;
    for (int i = 0; i < kSize; ++i) {
      seam_x += std::abs(at(m.albedo, layer, kSize - 1, i, 3) - at(m.albedo, layer, 0, i, 3));
      seam_y += std::abs(at(m.albedo, layer, i, kSize - 1, 3) - at(m.albedo, layer, i, 0, 3));
      inner_x +=
          std::abs(at(m.albedo, layer, kSize / 2 - 1, i, 3) - at(m.albedo, layer, kSize / 2, i, 3));
      inner_y +=
          std::abs(at(m.albedo, layer, i, kSize / 2 - 1, 3) - at(m.albedo, layer, i, kSize / 2, 3));
    }
    EXPECT_LT(seam_x, 2.5 * inner_x + 0.5) << "layer " << layer;
    EXPECT_LT(seam_y, 2.5 * inner_y + 0.5) << "layer " << layer;
  }
}

TEST(Materials, layers_are_varied_and_differ_from_each_other) {
  const MaterialImages m = generate_materials(kSize);
  for (int layer = 0; layer < kMaterialLayers; ++layer) {
    const double mean = layer_mean(m.albedo, layer, 3);
    double variance = 0;
    for (int y = 0; y < kSize; ++y)
      for (int x = 0; x < kSize; ++x)
        variance += std::pow(at(m.albedo, layer, x, y, 3) - mean, 2);
    EXPECT_GT(std::sqrt(variance / (kSize * kSize)), 0.05) << "layer " << layer << " is flat";
  }
  const int floor = static_cast<int>(MaterialLayer::kFloor);
  const int ceiling = static_cast<int>(MaterialLayer::kCeiling);
  // Dirt is warmer (red over blue) than the grey ceiling, and the damp ceiling glossier.
  EXPECT_GT(layer_mean(m.albedo, floor, 0) - layer_mean(m.albedo, floor, 2),
            layer_mean(m.albedo, ceiling, 0) - layer_mean(m.albedo, ceiling, 2) + 0.05);
  EXPECT_GT(layer_mean(m.normal, ceiling, 3), layer_mean(m.normal, floor, 3) + 0.05);
}

TEST(Materials, normals_are_unit_and_face_out_of_the_surface) {
  const MaterialImages m = generate_materials(kSize);
  double tilted = 0;
  for (int layer = 0; layer < kMaterialLayers; ++layer) {
    for (int y = 0; y < kSize; ++y) {
      for (int x = 0; x < kSize; ++x) {
        double n[3];
        for (int c = 0; c < 3; ++c)
          n[c] = at(m.normal, layer, x, y, c) * 2 - 1;
        EXPECT_NEAR(std::sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]), 1.0, 0.02);
        EXPECT_GT(n[2], 0.0);
        tilted += 1 - n[2];
      }
    }
  }
  EXPECT_GT(tilted / (kSize * kSize * kMaterialLayers), 0.01) << "the normal maps are flat";
}

}  // namespace
}  // namespace grotto::render
