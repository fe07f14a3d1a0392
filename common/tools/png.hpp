// A minimal PNG writer (8-bit RGB, stored deflate blocks): no dependency, enough for previews and
// screenshots (grotto-layout --png, grotto-client --screenshot).
#pragma once

#include <string>
#include <vector>

#include "core/result.hpp"

namespace grotto::tools {

// An RGB image (width * height * 3 bytes, top row first) as an uncompressed-deflate PNG file.
Status write_png(const std::string& path, const std::vector<unsigned char>& rgb, int width,
                 int height);

}  // namespace grotto::tools
