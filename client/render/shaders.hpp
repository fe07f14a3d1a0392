// The shader programs of client/render, from the files in shaders/ embedded at build time
// (client/render/CMakeLists.txt runs kernels/EmbedCl.cmake's generator over them).
#pragma once

#include <vector>

#include "client/render/gl.hpp"

namespace grotto::render {

std::vector<ShaderStage> room_stages();  // room.vert, room.tesc, room.tese, room.frag
std::vector<ShaderStage> cap_stages();   // cap.vert, cap.frag
std::vector<ShaderStage> text_stages();  // text.vert, text.frag (the overlay)

}  // namespace grotto::render
