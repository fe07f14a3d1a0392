// A small PNG writer and reader (8-bit RGB, zlib-compressed): enough for previews and screenshots
// (grotto-layout --png, grotto-client --screenshot) and for tests that look at them.
#pragma once

#include <string>
#include <vector>

#include "common/core/result.hpp"

namespace grotto::png {

// An RGB image (width * height * 3 bytes, top row first) as a PNG file.
Status write_png(const std::string& path, const std::vector<unsigned char>& rgb, int width,
                 int height);

struct RgbImage {
  int width = 0, height = 0;
  std::vector<unsigned char> rgb;  // width * height * 3 bytes, top row first
};
// Reads an 8-bit RGB, non-interlaced PNG (what write_png writes; any filter). Errors name the
// file and what is wrong with it.
Result<RgbImage> read_png(const std::string& path);

}  // namespace grotto::png
