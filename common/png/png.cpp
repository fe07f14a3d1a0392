#include "common/png/png.hpp"

#include <algorithm>
#include <array>
#include <cstdint>
#include <cstdlib>
#include <fstream>
#include <iterator>
#include <string>

#include <zlib.h>

namespace grotto::png {
namespace {

uint32_t crc32_of(const std::vector<unsigned char>& data) {
  return static_cast<uint32_t>(
      ::crc32(::crc32(0L, Z_NULL, 0), data.data(), static_cast<uInt>(data.size())));
}

void put_be32(std::vector<unsigned char>& out, uint32_t v) {
  for (int s = 24; s >= 0; s -= 8)
    out.push_back(static_cast<unsigned char>(v >> s));
}

void chunk(std::ofstream& f, const char* type, const std::vector<unsigned char>& data) {
  std::vector<unsigned char> body(type, type + 4);
  body.insert(body.end(), data.begin(), data.end());
  std::vector<unsigned char> head;
  put_be32(head, static_cast<uint32_t>(data.size()));
  std::vector<unsigned char> tail;
  put_be32(tail, crc32_of(body));
  f.write(reinterpret_cast<const char*>(head.data()), 4);
  f.write(reinterpret_cast<const char*>(body.data()), static_cast<std::streamsize>(body.size()));
  f.write(reinterpret_cast<const char*>(tail.data()), 4);
}

}  // namespace

Status write_png(const std::string& path, const std::vector<unsigned char>& rgb, int width,
                 int height) {
  if (rgb.size() != static_cast<size_t>(width) * height * 3) {
    return invalid_argument("write_png: image size does not match width x height x 3");
  }
  // Scanlines with the Sub filter (each byte less its left neighbour: smooth rock and dark fog
  // become runs of small numbers), compressed by zlib.
  std::vector<unsigned char> raw;
  raw.reserve(rgb.size() + height);
  const size_t stride = static_cast<size_t>(width) * 3;
  for (int y = 0; y < height; ++y) {
    const unsigned char* row = rgb.data() + static_cast<size_t>(y) * stride;
    raw.push_back(1);
    for (size_t i = 0; i < stride; ++i)
      raw.push_back(static_cast<unsigned char>(row[i] - (i >= 3 ? row[i - 3] : 0)));
  }
  uLongf z_size = compressBound(static_cast<uLong>(raw.size()));
  std::vector<unsigned char> z(z_size);
  if (compress2(z.data(), &z_size, raw.data(), static_cast<uLong>(raw.size()), 6) != Z_OK)
    return Error{ErrorCode::kInternal, "write_png: zlib could not compress the image"};
  z.resize(z_size);
  std::ofstream f(path, std::ios::binary);
  const unsigned char signature[8] = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1a, '\n'};
  f.write(reinterpret_cast<const char*>(signature), 8);
  std::vector<unsigned char> ihdr;
  put_be32(ihdr, static_cast<uint32_t>(width));
  put_be32(ihdr, static_cast<uint32_t>(height));
  ihdr.insert(ihdr.end(), {8, 2, 0, 0, 0});  // 8-bit RGB, deflate, adaptive filters, no interlace
  chunk(f, "IHDR", ihdr);
  chunk(f, "IDAT", z);
  chunk(f, "IEND", {});
  f.close();
  if (!f) return Error{ErrorCode::kUnavailable, "cannot write " + path};
  return {};
}

namespace {

uint32_t be32(const std::vector<unsigned char>& b, size_t at) {
  return static_cast<uint32_t>(b[at]) << 24 | static_cast<uint32_t>(b[at + 1]) << 16 |
         static_cast<uint32_t>(b[at + 2]) << 8 | b[at + 3];
}

int paeth(int a, int b, int c) {
  const int p = a + b - c, pa = std::abs(p - a), pb = std::abs(p - b), pc = std::abs(p - c);
  return pa <= pb && pa <= pc ? a : (pb <= pc ? b : c);
}

}  // namespace

Result<RgbImage> read_png(const std::string& path) {
  auto bad = [&](const std::string& why) {
    return Error{ErrorCode::kInvalidArgument, path + ": " + why};
  };
  std::ifstream f(path, std::ios::binary);
  if (!f) return Error{ErrorCode::kNotFound, path + ": cannot open"};
  const std::vector<unsigned char> b((std::istreambuf_iterator<char>(f)), {});
  static const unsigned char kSignature[8] = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1a, '\n'};
  if (b.size() < 33 || !std::equal(kSignature, kSignature + 8, b.begin()))
    return bad("not a PNG file");
  RgbImage image;
  std::vector<unsigned char> z;
  bool header = false;
  for (size_t at = 8; at + 12 <= b.size();) {
    const uint32_t length = be32(b, at);
    if (length > b.size() - at - 12) return bad("chunk runs past the end of the file");
    const std::string type(b.begin() + static_cast<long>(at) + 4,
                           b.begin() + static_cast<long>(at) + 8);
    const size_t data = at + 8;
    if (type == "IHDR") {
      if (length != 13) return bad("IHDR is not 13 bytes");
      image.width = static_cast<int>(be32(b, data));
      image.height = static_cast<int>(be32(b, data + 4));
      if (b[data + 8] != 8 || b[data + 9] != 2 || b[data + 12] != 0)
        return bad("not 8-bit RGB without interlacing");
      if (image.width <= 0 || image.height <= 0 || image.width > 65536 || image.height > 65536)
        return bad("size out of range");
      header = true;
    } else if (type == "IDAT") {
      z.insert(z.end(), b.begin() + static_cast<long>(data),
               b.begin() + static_cast<long>(data + length));
    }
    at = data + length + 4;
  }
  if (!header) return bad("no IHDR chunk");
  const size_t stride = static_cast<size_t>(image.width) * 3;
  std::vector<unsigned char> raw((stride + 1) * static_cast<size_t>(image.height));
  uLongf raw_size = static_cast<uLongf>(raw.size());
  if (uncompress(raw.data(), &raw_size, z.data(), static_cast<uLong>(z.size())) != Z_OK ||
      raw_size != raw.size())
    return bad("image data does not inflate to width x height pixels");
  image.rgb.resize(stride * static_cast<size_t>(image.height));
  for (int y = 0; y < image.height; ++y) {
    const unsigned char* in = &raw[static_cast<size_t>(y) * (stride + 1)];
    unsigned char* out = &image.rgb[static_cast<size_t>(y) * stride];
    const unsigned char* up = y > 0 ? out - stride : nullptr;
    for (size_t i = 0; i < stride; ++i) {
      const int a = i >= 3 ? out[i - 3] : 0, u = up ? up[i] : 0, c = up && i >= 3 ? up[i - 3] : 0;
      int predicted = 0;
      switch (in[0]) {
        case 0:
          predicted = 0;
          break;
        case 1:
          predicted = a;
          break;
        case 2:
          predicted = u;
          break;
        case 3:
          predicted = (a + u) / 2;
          break;
        case 4:
          predicted = paeth(a, u, c);
          break;
        default:
          return bad("unknown filter " + std::to_string(in[0]) + " in row " + std::to_string(y));
      }
      out[i] = static_cast<unsigned char>(in[1 + i] + predicted);
    }
  }
  return image;
}

}  // namespace grotto::png
