#include "client/render/materials.hpp"

#include <algorithm>
#include <cmath>
#include <string>

namespace grotto::render {
namespace {

constexpr double kTau = 6.283185307179586;

// A 32-bit integer hash of a lattice point (lowbias32 mixing), in [0, 1).
double lattice(int x, int y, uint32_t salt) {
  uint32_t h = static_cast<uint32_t>(x) * 0x8da6b343u ^ static_cast<uint32_t>(y) * 0xd8163841u ^
               salt * 0xcb1ab31fu;
  h ^= h >> 16;
  h *= 0x7feb352du;
  h ^= h >> 15;
  h *= 0x846ca68bu;
  h ^= h >> 16;
  return (h >> 8) * (1.0 / 16777216.0);
}

int wrap(int i, int period) {
  return ((i % period) + period) % period;
}

// Value noise on a lattice of `period` cells per unit, repeating every unit: u, v in [0, 1).
double periodic_noise(double u, double v, int period, uint32_t salt) {
  const double x = u * period, y = v * period;
  const int x0 = static_cast<int>(std::floor(x)), y0 = static_cast<int>(std::floor(y));
  const double fx = x - x0, fy = y - y0;
  const double sx = fx * fx * (3 - 2 * fx), sy = fy * fy * (3 - 2 * fy);
  auto at = [&](int dx, int dy) {
    return lattice(wrap(x0 + dx, period), wrap(y0 + dy, period), salt);
  };
  const double top = at(0, 0) + (at(1, 0) - at(0, 0)) * sx;
  const double bottom = at(0, 1) + (at(1, 1) - at(0, 1)) * sx;
  return top + (bottom - top) * sy;
}

// Octaves of periodic noise, each twice the frequency and `gain` times the amplitude; in [0, 1].
double fbm(double u, double v, int period, int octaves, double gain, uint32_t salt) {
  double sum = 0, amplitude = 1, total = 0;
  for (int o = 0; o < octaves; ++o, period *= 2, amplitude *= gain) {
    sum += amplitude * periodic_noise(u, v, period, salt + static_cast<uint32_t>(o) * 101u);
    total += amplitude;
  }
  return sum / total;
}

// Distance (in cells) from (u, v) to the nearest of one jittered point per cell, periodic.
double cell_distance(double u, double v, int period, uint32_t salt) {
  const double x = u * period, y = v * period;
  const int cx = static_cast<int>(std::floor(x)), cy = static_cast<int>(std::floor(y));
  double best = 8;
  for (int dy = -1; dy <= 1; ++dy) {
    for (int dx = -1; dx <= 1; ++dx) {
      const int ix = cx + dx, iy = cy + dy;
      const double px = ix + 0.15 + 0.7 * lattice(wrap(ix, period), wrap(iy, period), salt);
      const double py = iy + 0.15 + 0.7 * lattice(wrap(ix, period), wrap(iy, period), salt + 7u);
      best = std::min(best, std::hypot(x - px, y - py));
    }
  }
  return best;
}

double smoothstep(double e0, double e1, double x) {
  const double t = std::clamp((x - e0) / (e1 - e0), 0.0, 1.0);
  return t * t * (3 - 2 * t);
}

struct Texel {
  double r, g, b, height, gloss;
};

Texel mix(const Texel& a, const Texel& b, double t) {
  return {a.r + (b.r - a.r) * t, a.g + (b.g - a.g) * t, a.b + (b.b - a.b) * t,
          a.height + (b.height - a.height) * t, a.gloss + (b.gloss - a.gloss) * t};
}

// Dry dirt with a scatter of rounded pebbles standing out of it.
Texel floor_texel(double u, double v) {
  const double dirt = fbm(u, v, 8, 5, 0.55, 11);
  // Pebbles of varied size, scattered unevenly: the noise thins them out in places.
  const double size = 0.18 + 0.2 * fbm(u, v, 5, 2, 0.5, 19);
  const double pebble = smoothstep(size, size - 0.12, cell_distance(u, v, 7, 23)) *
                        smoothstep(0.35, 0.55, fbm(u, v, 3, 2, 0.5, 29));
  const double speckle = fbm(u, v, 64, 2, 0.5, 31);
  const Texel soil{0.30 + 0.16 * dirt, 0.24 + 0.13 * dirt, 0.17 + 0.09 * dirt, 0.35 * dirt, 0.08};
  const Texel stone{0.3 + 0.14 * speckle, 0.27 + 0.12 * speckle, 0.23 + 0.1 * speckle,
                    0.35 + 0.3 * pebble, 0.3};
  return mix(soil, stone, pebble);
}

// Sedimentary bands, warped by noise, with dark cracks; bands run along u (horizontal on walls).
Texel wall_texel(double u, double v) {
  const double warp = fbm(u, v, 4, 4, 0.5, 41);
  const double band = 0.5 + 0.5 * std::sin(kTau * (3 * v + 0.6 * warp));
  const double grain = fbm(u, v, 16, 4, 0.5, 53);
  const double crack = smoothstep(0.012, 0.0, std::abs(fbm(u, v, 5, 5, 0.6, 67) - 0.5));
  const double shade = 0.65 * band + 0.35 * grain;
  Texel t{0.26 + 0.3 * shade, 0.23 + 0.25 * shade, 0.2 + 0.19 * shade,
          0.3 + 0.3 * band + 0.4 * grain, 0.12 + 0.1 * band};
  t.r *= 1 - 0.35 * crack, t.g *= 1 - 0.35 * crack, t.b *= 1 - 0.35 * crack;
  t.height *= 1 - 0.4 * crack;
  return t;
}

// Smooth grey stone with damp patches: darker, glossier where wet.
Texel ceiling_texel(double u, double v) {
  const double stone = fbm(u, v, 4, 6, 0.5, 79);
  const double damp = smoothstep(0.5, 0.7, fbm(u, v, 3, 3, 0.5, 97));
  const Texel dry{0.36 + 0.14 * stone, 0.36 + 0.14 * stone, 0.38 + 0.15 * stone, stone, 0.15};
  const Texel wet{0.2 + 0.08 * stone, 0.22 + 0.08 * stone, 0.25 + 0.09 * stone, stone, 0.7};
  return mix(dry, wet, damp);
}

uint8_t to_byte(double x) {
  return static_cast<uint8_t>(std::lround(std::clamp(x, 0.0, 1.0) * 255.0));
}

bool valid_size(int size) {
  return size >= 16 && size <= 2048 && (size & (size - 1)) == 0;
}

}  // namespace

MaterialImages generate_materials(int size) {
  MaterialImages out;
  if (!valid_size(size)) return out;
  out.size = size;
  const size_t layer_texels = static_cast<size_t>(size) * static_cast<size_t>(size);
  out.albedo.resize(layer_texels * kMaterialLayers * 4);
  out.normal.resize(out.albedo.size());
  std::vector<double> height(layer_texels), gloss(layer_texels);
  for (int layer = 0; layer < kMaterialLayers; ++layer) {
    uint8_t* albedo = out.albedo.data() + layer * layer_texels * 4;
    for (int y = 0; y < size; ++y) {
      for (int x = 0; x < size; ++x) {
        const double u = (x + 0.5) / size, v = (y + 0.5) / size;
        const Texel t = layer == 0   ? floor_texel(u, v)
                        : layer == 1 ? wall_texel(u, v)
                                     : ceiling_texel(u, v);
        const size_t i = static_cast<size_t>(y) * size + x;
        height[i] = std::clamp(t.height, 0.0, 1.0);
        gloss[i] = t.gloss;
        albedo[i * 4 + 0] = to_byte(t.r);
        albedo[i * 4 + 1] = to_byte(t.g);
        albedo[i * 4 + 2] = to_byte(t.b);
        albedo[i * 4 + 3] = to_byte(height[i]);
      }
    }
    // The normal of the height field (central differences, wrapping like the texture), with a
    // relief of `kRelief` height units per texel spacing.
    constexpr double kRelief = 3.0;
    uint8_t* normal = out.normal.data() + layer * layer_texels * 4;
    auto h = [&](int x, int y) { return height[wrap(y, size) * size + wrap(x, size)]; };
    for (int y = 0; y < size; ++y) {
      for (int x = 0; x < size; ++x) {
        const double dx = (h(x + 1, y) - h(x - 1, y)) * 0.5 * kRelief;
        const double dy = (h(x, y + 1) - h(x, y - 1)) * 0.5 * kRelief;
        const double n = std::sqrt(dx * dx + dy * dy + 1);
        const size_t i = static_cast<size_t>(y) * size + x;
        normal[i * 4 + 0] = to_byte(-dx / n * 0.5 + 0.5);
        normal[i * 4 + 1] = to_byte(-dy / n * 0.5 + 0.5);
        normal[i * 4 + 2] = to_byte(1 / n * 0.5 + 0.5);
        normal[i * 4 + 3] = to_byte(gloss[i]);
      }
    }
  }
  return out;
}

Result<Materials> Materials::create(int size) {
  if (!valid_size(size))
    return invalid_argument("material texture size must be a power of two in [16, 2048], got " +
                            std::to_string(size));
  const MaterialImages images = generate_materials(size);
  Materials m;
  auto upload = [&](const std::vector<uint8_t>& texels) {
    Texture texture = make_texture();
    glBindTexture(GL_TEXTURE_2D_ARRAY, texture.get());
    glTexImage3D(GL_TEXTURE_2D_ARRAY, 0, GL_RGBA8, size, size, kMaterialLayers, 0, GL_RGBA,
                 GL_UNSIGNED_BYTE, texels.data());
    glGenerateMipmap(GL_TEXTURE_2D_ARRAY);
    glTexParameteri(GL_TEXTURE_2D_ARRAY, GL_TEXTURE_MIN_FILTER, GL_LINEAR_MIPMAP_LINEAR);
    glTexParameteri(GL_TEXTURE_2D_ARRAY, GL_TEXTURE_MAG_FILTER, GL_LINEAR);
    glTexParameteri(GL_TEXTURE_2D_ARRAY, GL_TEXTURE_WRAP_S, GL_REPEAT);
    glTexParameteri(GL_TEXTURE_2D_ARRAY, GL_TEXTURE_WRAP_T, GL_REPEAT);
    glBindTexture(GL_TEXTURE_2D_ARRAY, 0);
    return texture;
  };
  m.albedo_ = upload(images.albedo);
  m.normal_ = upload(images.normal);
  return m;
}

void Materials::bind(GLuint albedo_unit, GLuint normal_unit) const {
  glActiveTexture(GL_TEXTURE0 + albedo_unit);
  glBindTexture(GL_TEXTURE_2D_ARRAY, albedo_.get());
  glActiveTexture(GL_TEXTURE0 + normal_unit);
  glBindTexture(GL_TEXTURE_2D_ARRAY, normal_.get());
  glActiveTexture(GL_TEXTURE0);
}

}  // namespace grotto::render
