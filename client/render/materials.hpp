// The cave's rock materials, generated at start-up (no files, no downloads): three tileable
// layers (floor: dirt and pebbles; walls: layered rock with cracks; ceiling: smooth damp stone),
// each an albedo with its height and a tangent-space normal map derived from that height with its
// gloss. shaders/room.frag projects them triplanarly (thesis §3.3.2) and perturbs the normal in a
// tangent frame synthesized from the normal alone, since the mesh has no texture coordinates.
#pragma once

#include <cstdint>
#include <vector>

#include "client/render/gl.hpp"
#include "core/result.hpp"

namespace grotto::render {

enum class MaterialLayer { kFloor = 0, kWall = 1, kCeiling = 2 };
inline constexpr int kMaterialLayers = 3;

// The texels of every layer, layer after layer, rows top to bottom. Pure: testable without GL.
struct MaterialImages {
  int size = 0;                 // width and height of each layer, a power of two
  std::vector<uint8_t> albedo;  // RGBA8: rgb albedo, a height (0 low, 255 high)
  std::vector<uint8_t> normal;  // RGBA8: tangent-space normal (xyz * 0.5 + 0.5), a gloss
};

// Deterministic: the same size gives the same texels. `size` is a power of two in [16, 2048].
MaterialImages generate_materials(int size);

// The images as two mipmapped, repeating GL_TEXTURE_2D_ARRAYs.
class Materials {
 public:
  static Result<Materials> create(int size = 256);
  // Binds the albedo array to texture unit `albedo_unit` and the normal array to `normal_unit`.
  void bind(GLuint albedo_unit, GLuint normal_unit) const;

 private:
  Texture albedo_;
  Texture normal_;
};

}  // namespace grotto::render
