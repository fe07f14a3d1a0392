#include "tools/preview.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

namespace grotto::tools {

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

}  // namespace grotto::tools
