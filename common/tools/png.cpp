#include "tools/png.hpp"

#include <algorithm>
#include <array>
#include <cstdint>
#include <fstream>

namespace grotto::tools {
namespace {

// PNG's CRC-32 (ISO 3309) and zlib's Adler-32, both small enough to own.
uint32_t crc32(const unsigned char* data, size_t n, uint32_t crc = 0) {
  static const std::array<uint32_t, 256> table = [] {
    std::array<uint32_t, 256> t{};
    for (uint32_t i = 0; i < 256; ++i) {
      uint32_t c = i;
      for (int k = 0; k < 8; ++k)
        c = (c & 1) ? 0xedb88320u ^ (c >> 1) : c >> 1;
      t[i] = c;
    }
    return t;
  }();
  crc = ~crc;
  for (size_t i = 0; i < n; ++i)
    crc = table[(crc ^ data[i]) & 0xff] ^ (crc >> 8);
  return ~crc;
}

uint32_t adler32(const std::vector<unsigned char>& data) {
  uint32_t a = 1, b = 0;
  for (unsigned char c : data) {
    a = (a + c) % 65521;
    b = (b + a) % 65521;
  }
  return (b << 16) | a;
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
  put_be32(tail, crc32(body.data(), body.size()));
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
  // Scanlines with filter byte 0, in stored (uncompressed) deflate blocks of up to 65535 bytes.
  std::vector<unsigned char> raw;
  raw.reserve(rgb.size() + height);
  for (int y = 0; y < height; ++y) {
    raw.push_back(0);
    raw.insert(raw.end(), rgb.begin() + static_cast<size_t>(y) * width * 3,
               rgb.begin() + static_cast<size_t>(y + 1) * width * 3);
  }
  std::vector<unsigned char> z{0x78, 0x01};
  for (size_t at = 0; at < raw.size(); at += 65535) {
    size_t n = std::min<size_t>(65535, raw.size() - at);
    z.push_back(at + n == raw.size() ? 1 : 0);
    z.push_back(static_cast<unsigned char>(n & 0xff));
    z.push_back(static_cast<unsigned char>(n >> 8));
    z.push_back(static_cast<unsigned char>(~n & 0xff));
    z.push_back(static_cast<unsigned char>((~n >> 8) & 0xff));
    z.insert(z.end(), raw.begin() + at, raw.begin() + at + n);
  }
  put_be32(z, adler32(raw));
  std::ofstream f(path, std::ios::binary);
  const unsigned char signature[8] = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1a, '\n'};
  f.write(reinterpret_cast<const char*>(signature), 8);
  std::vector<unsigned char> ihdr;
  put_be32(ihdr, static_cast<uint32_t>(width));
  put_be32(ihdr, static_cast<uint32_t>(height));
  ihdr.insert(ihdr.end(), {8, 2, 0, 0, 0});  // 8-bit RGB, deflate, no filter, no interlace
  chunk(f, "IHDR", ihdr);
  chunk(f, "IDAT", z);
  chunk(f, "IEND", {});
  f.close();
  if (!f) return Error{ErrorCode::kUnavailable, "cannot write " + path};
  return {};
}

}  // namespace grotto::tools
