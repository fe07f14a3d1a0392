// The shader programs of client/render, from the files in shaders/ embedded at build time
// (client/render/CMakeLists.txt runs common/kernels/EmbedCl.cmake's generator over them).
#pragma once

#include <vector>

#include "client/render/gl.hpp"

namespace grotto::render {

std::vector<ShaderStage> room_stages();       // room.vert, room.tesc, room.tese, room.frag
std::vector<ShaderStage> formation_stages();  // formation.vert, room.frag (speleothem instances)
std::vector<ShaderStage> cap_stages();        // cap.vert, cap.frag
std::vector<ShaderStage> text_stages();       // text.vert, text.frag (the overlay)
// Post passes over a full-screen triangle (post.vert): Kawase bloom and the composite.
std::vector<ShaderStage> bloom_stages();      // post_bloom.frag: downsample or one Kawase pass
std::vector<ShaderStage> composite_stages();  // post_composite.frag: motion blur + bloom

}  // namespace grotto::render
