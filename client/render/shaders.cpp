#include "client/render/shaders.hpp"

#include "embedded_cl/cap_frag.hpp"
#include "embedded_cl/cap_vert.hpp"
#include "embedded_cl/room_frag.hpp"
#include "embedded_cl/room_tesc.hpp"
#include "embedded_cl/room_tese.hpp"
#include "embedded_cl/room_vert.hpp"
#include "embedded_cl/text_frag.hpp"
#include "embedded_cl/text_vert.hpp"

namespace grotto::render {

std::vector<ShaderStage> room_stages() {
  return {{GL_VERTEX_SHADER, kernels::source_room_vert(), "room.vert"},
          {GL_TESS_CONTROL_SHADER, kernels::source_room_tesc(), "room.tesc"},
          {GL_TESS_EVALUATION_SHADER, kernels::source_room_tese(), "room.tese"},
          {GL_FRAGMENT_SHADER, kernels::source_room_frag(), "room.frag"}};
}

std::vector<ShaderStage> cap_stages() {
  return {{GL_VERTEX_SHADER, kernels::source_cap_vert(), "cap.vert"},
          {GL_FRAGMENT_SHADER, kernels::source_cap_frag(), "cap.frag"}};
}

std::vector<ShaderStage> text_stages() {
  return {{GL_VERTEX_SHADER, kernels::source_text_vert(), "text.vert"},
          {GL_FRAGMENT_SHADER, kernels::source_text_frag(), "text.frag"}};
}

}  // namespace grotto::render
