#include "client/render/shaders.hpp"

#include <string>

#include "embedded_cl/cap_frag.hpp"
#include "embedded_cl/cap_vert.hpp"
#include "embedded_cl/formation_glsl.hpp"
#include "embedded_cl/formation_vert.hpp"
#include "embedded_cl/lights_glsl.hpp"
#include "embedded_cl/lod_glsl.hpp"
#include "embedded_cl/post_bloom_frag.hpp"
#include "embedded_cl/post_composite_frag.hpp"
#include "embedded_cl/post_vert.hpp"
#include "embedded_cl/relief_glsl.hpp"
#include "embedded_cl/room_frag.hpp"
#include "embedded_cl/room_tesc.hpp"
#include "embedded_cl/room_tese.hpp"
#include "embedded_cl/room_vert.hpp"
#include "embedded_cl/text_frag.hpp"
#include "embedded_cl/text_vert.hpp"

namespace grotto::render {
namespace {

// GLSL has no #include: the line `#pragma grotto_include "relief.glsl"` is replaced by that file,
// so the relief is written once for every stage that needs it (and for the CPU, relief.hpp);
// likewise "lights.glsl" (the world's lights and flares, room.frag only) and "lod.glsl" (the
// tessellation levels: room.tesc sets them, room.tese derives the relief's sampling step) and
// "formation.glsl" (a formation instance's shape: formation.vert).
std::string with_relief(std::string_view source) {
  std::string out(source);
  for (auto [line, text] : {std::pair{std::string_view("#pragma grotto_include \"relief.glsl\""),
                                      kernels::source_relief_glsl()},
                            std::pair{std::string_view("#pragma grotto_include \"lights.glsl\""),
                                      kernels::source_lights_glsl()},
                            std::pair{std::string_view("#pragma grotto_include \"lod.glsl\""),
                                      kernels::source_lod_glsl()},
                            std::pair{std::string_view("#pragma grotto_include \"formation.glsl\""),
                                      kernels::source_formation_glsl()}}) {
    const size_t at = out.find(line);
    if (at != std::string::npos) out.replace(at, line.size(), text);
  }
  return out;
}

}  // namespace

std::vector<ShaderStage> room_stages() {
  static const std::string tesc = with_relief(kernels::source_room_tesc());  // lod.glsl
  static const std::string tese = with_relief(kernels::source_room_tese());
  static const std::string frag = with_relief(kernels::source_room_frag());
  return {{GL_VERTEX_SHADER, kernels::source_room_vert(), "room.vert"},
          {GL_TESS_CONTROL_SHADER, tesc, "room.tesc"},
          {GL_TESS_EVALUATION_SHADER, tese, "room.tese"},
          {GL_FRAGMENT_SHADER, frag, "room.frag"}};
}

std::vector<ShaderStage> formation_stages() {
  static const std::string vert = with_relief(kernels::source_formation_vert());
  static const std::string frag = with_relief(kernels::source_room_frag());
  return {{GL_VERTEX_SHADER, vert, "formation.vert"}, {GL_FRAGMENT_SHADER, frag, "room.frag"}};
}

std::vector<ShaderStage> cap_stages() {
  return {{GL_VERTEX_SHADER, kernels::source_cap_vert(), "cap.vert"},
          {GL_FRAGMENT_SHADER, kernels::source_cap_frag(), "cap.frag"}};
}

std::vector<ShaderStage> text_stages() {
  return {{GL_VERTEX_SHADER, kernels::source_text_vert(), "text.vert"},
          {GL_FRAGMENT_SHADER, kernels::source_text_frag(), "text.frag"}};
}

std::vector<ShaderStage> bloom_stages() {
  return {{GL_VERTEX_SHADER, kernels::source_post_vert(), "post.vert"},
          {GL_FRAGMENT_SHADER, kernels::source_post_bloom_frag(), "post_bloom.frag"}};
}

std::vector<ShaderStage> composite_stages() {
  return {{GL_VERTEX_SHADER, kernels::source_post_vert(), "post.vert"},
          {GL_FRAGMENT_SHADER, kernels::source_post_composite_frag(), "post_composite.frag"}};
}

}  // namespace grotto::render
