#include "preview.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <fstream>
#include <limits>

namespace grotto::tools {
namespace {

Vec3 cross(Vec3 a, Vec3 b) {
  return {a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x};
}

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

std::vector<unsigned char> render_preview(const std::vector<mesh::RoomMesh>& meshes,
                                          const PreviewOptions& o) {
  const int w = o.width, h = o.height;
  std::vector<unsigned char> rgb(static_cast<size_t>(w) * h * 3, 0);
  for (size_t i = 0; i < rgb.size(); i += 3) {
    rgb[i] = 15, rgb[i + 1] = 17, rgb[i + 2] = 21;
  }
  // Camera basis: forward along the view direction, up as close to world +y as possible.
  Vec3 fwd = normalize(o.view_direction);
  Vec3 right = normalize(cross(fwd, Vec3{0, 1, 0}));
  Vec3 up = cross(right, fwd);
  double lo_u = 1e300, hi_u = -1e300, lo_v = 1e300, hi_v = -1e300, lo_y = 1e300, hi_y = -1e300;
  for (const auto& m : meshes) {
    for (size_t v = 0; v < m.vertex_count(); ++v) {
      Vec3 p = m.world_position(v);
      lo_u = std::min(lo_u, dot(p, right)), hi_u = std::max(hi_u, dot(p, right));
      lo_v = std::min(lo_v, dot(p, up)), hi_v = std::max(hi_v, dot(p, up));
      lo_y = std::min(lo_y, p.y), hi_y = std::max(hi_y, p.y);
    }
  }
  if (meshes.empty() || hi_u <= lo_u || hi_v <= lo_v) return rgb;
  double scale = 0.95 * std::min(w / (hi_u - lo_u), h / (hi_v - lo_v));
  double cu = 0.5 * (lo_u + hi_u), cv = 0.5 * (lo_v + hi_v);
  std::vector<float> depth(static_cast<size_t>(w) * h, std::numeric_limits<float>::max());
  const Vec3 light = normalize(Vec3{-0.3, 1.0, 0.2});

  for (const auto& m : meshes) {
    for (size_t t = 0; t < m.indices.size(); t += 3) {
      Vec3 p[3];
      double sx[3], sy[3], sz[3];
      float mineral = 0;
      for (int k = 0; k < 3; ++k) {
        p[k] = m.world_position(m.indices[t + k]);
        sx[k] = 0.5 * w + (dot(p[k], right) - cu) * scale;
        sy[k] = 0.5 * h - (dot(p[k], up) - cv) * scale;
        sz[k] = dot(p[k], fwd);
        mineral += m.mineral[m.indices[t + k]] / 3;
      }
      Vec3 n = cross(p[1] - p[0], p[2] - p[0]);
      double len = length(n);
      if (len == 0) continue;
      n = n / len;
      if (dot(n, fwd) > 0) n = -n;  // lit from both sides: seen from outside the cave
      double shade = 0.25 + 0.75 * std::max(0.0, dot(n, light));
      double height = (0.5 * (p[0].y + p[1].y) - lo_y) / std::max(1e-9, hi_y - lo_y);
      // Rock from cool grey-blue (deep) to warm sandstone (high); minerals glow teal.
      double r = (0.45 + 0.35 * height) * shade, g = (0.47 + 0.22 * height) * shade,
             b = (0.55 - 0.15 * height) * shade;
      mineral *= 0.45f;
      r = r * (1 - 0.6 * mineral) + 0.2 * mineral, g = g * (1 - 0.6 * mineral) + 0.8 * mineral,
      b = b * (1 - 0.6 * mineral) + 0.75 * mineral;
      int x0 = std::max(0, static_cast<int>(std::floor(std::min({sx[0], sx[1], sx[2]}))));
      int x1 = std::min(w - 1, static_cast<int>(std::ceil(std::max({sx[0], sx[1], sx[2]}))));
      int y0 = std::max(0, static_cast<int>(std::floor(std::min({sy[0], sy[1], sy[2]}))));
      int y1 = std::min(h - 1, static_cast<int>(std::ceil(std::max({sy[0], sy[1], sy[2]}))));
      double area = (sx[1] - sx[0]) * (sy[2] - sy[0]) - (sx[2] - sx[0]) * (sy[1] - sy[0]);
      if (area == 0) continue;
      for (int y = y0; y <= y1; ++y) {
        for (int x = x0; x <= x1; ++x) {
          double px = x + 0.5, py = y + 0.5;
          double w0 = ((sx[1] - px) * (sy[2] - py) - (sx[2] - px) * (sy[1] - py)) / area;
          double w1 = ((sx[2] - px) * (sy[0] - py) - (sx[0] - px) * (sy[2] - py)) / area;
          double w2 = 1 - w0 - w1;
          if (w0 < 0 || w1 < 0 || w2 < 0) continue;
          float z = static_cast<float>(w0 * sz[0] + w1 * sz[1] + w2 * sz[2]);
          size_t i = static_cast<size_t>(y) * w + x;
          if (z >= depth[i]) continue;
          depth[i] = z;
          rgb[3 * i] = static_cast<unsigned char>(255 * std::clamp(r, 0.0, 1.0));
          rgb[3 * i + 1] = static_cast<unsigned char>(255 * std::clamp(g, 0.0, 1.0));
          rgb[3 * i + 2] = static_cast<unsigned char>(255 * std::clamp(b, 0.0, 1.0));
        }
      }
    }
  }
  return rgb;
}

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
