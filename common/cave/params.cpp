#include "common/cave/params.hpp"

#include <algorithm>
#include <cmath>

#include "common/core/random.hpp"

namespace grotto::cave {
namespace {

constexpr uint64_t kRegionStream = 0x726567696f6e0001ull;  // "region"

std::string number(double v) {
  char buf[32];
  std::snprintf(buf, sizeof buf, "%g", v);
  return buf;
}

// Collects the first problem found, naming the field.
class Checker {
 public:
  void finite_positive(const std::string& field, double v) {
    if (!std::isfinite(v))
      fail(field + " must be a finite number (got " + number(v) + ")");
    else if (v <= 0)
      fail(field + " must be > 0 (got " + number(v) + ")");
  }
  void probability(const std::string& field, double v) {
    if (!(v >= 0.0 && v <= 1.0)) fail(field + " must be in [0, 1] (got " + number(v) + ")");
  }
  void ordered(const std::string& lo_field, double lo, const std::string& hi_field, double hi) {
    if (lo > hi) {
      fail(lo_field + " (" + number(lo) + ") must not exceed " + hi_field + " (" + number(hi) +
           ")");
    }
  }
  void int_range(const std::string& field, int v, int lo, int hi) {
    if (v < lo || v > hi) {
      fail(field + " must be in [" + std::to_string(lo) + ", " + std::to_string(hi) + "] (got " +
           std::to_string(v) + ")");
    }
  }
  void fail(std::string message) {
    if (first_.empty()) first_ = std::move(message);
  }
  Status status() const {
    if (first_.empty()) return {};
    return invalid_argument("invalid layout parameters: " + first_);
  }

 private:
  std::string first_;
};

double smooth(double t) {
  return t * t * (3.0 - 2.0 * t);
}

// Value noise in [0, 1): a hashed lattice value per integer point, blended with smoothstep.
double value_noise(uint64_t seed, int channel, double x, double y, double z) {
  double fx = std::floor(x), fy = std::floor(y), fz = std::floor(z);
  auto ix = static_cast<int64_t>(fx), iy = static_cast<int64_t>(fy), iz = static_cast<int64_t>(fz);
  double tx = smooth(x - fx), ty = smooth(y - fy), tz = smooth(z - fz);
  auto lattice = [&](int64_t dx, int64_t dy, int64_t dz) {
    uint64_t h = hash_words(seed, kRegionStream, channel, ix + dx, iy + dy, iz + dz);
    return static_cast<double>(h >> 11) * 0x1.0p-53;
  };
  double c[2][2];
  for (int dy = 0; dy < 2; ++dy) {
    for (int dz = 0; dz < 2; ++dz) {
      double a = lattice(0, dy, dz), b = lattice(1, dy, dz);
      c[dy][dz] = a + (b - a) * tx;
    }
  }
  double c0 = c[0][0] + (c[1][0] - c[0][0]) * ty;
  double c1 = c[0][1] + (c[1][1] - c[0][1]) * ty;
  return c0 + (c1 - c0) * tz;
}

}  // namespace

std::array<Character, kCharacterCount> LayoutParams::default_characters() {
  Character maze;  // flat maze of narrow tunnels (thesis Figure 3-3, top)
  maze.name = "maze";
  maze.room_count = 45;
  maze.big_probability = 0.05;
  maze.small_radius_min = 2.5;
  maze.small_radius_max = 3.5;
  maze.big_radius_min = 5.0;
  maze.big_radius_max = 7.0;
  maze.bias = {1.0, 0.12, 1.0};
  maze.tunnel_chance = 0.7;
  maze.loops = 5;               // mazes are interconnected
  maze.hall_probability = 0.3;  // a breakdown chamber where the maze collapsed
  maze.hall_radius_min = 15.0;
  maze.hall_radius_max = 20.0;

  Character shafts;  // vertical shafts (Figure 3-3, lower right)
  shafts.name = "shafts";
  shafts.room_count = 35;
  shafts.big_probability = 0.15;
  shafts.small_radius_min = 2.5;
  shafts.small_radius_max = 4.0;
  shafts.big_radius_min = 5.0;
  shafts.big_radius_max = 8.0;
  shafts.bias = {0.25, 1.0, 0.25};
  shafts.tunnel_chance = 0.6;
  shafts.loops = 3;
  shafts.hall_probability = 0.4;  // a tall chamber where shafts meet
  shafts.hall_radius_min = 15.0;
  shafts.hall_radius_max = 22.0;

  Character caverns;  // large open spaces
  caverns.name = "caverns";
  caverns.room_count = 22;
  caverns.big_probability = 0.6;
  caverns.small_radius_min = 3.0;
  caverns.small_radius_max = 4.5;
  caverns.big_radius_min = 8.0;
  caverns.big_radius_max = 13.0;
  caverns.bias = {1.0, 0.4, 1.0};
  caverns.tunnel_chance = 0.2;
  caverns.loops = 2;
  caverns.hall_probability = 1.0;  // every cavern sector has a hall 32-68 m across
  caverns.hall_radius_min = 16.0;
  caverns.hall_radius_max = 34.0;
  return {maze, shafts, caverns};
}

LayoutParams LayoutParams::uniform(const Character& c) {
  LayoutParams p;
  p.characters = {c, c, c};
  return p;
}

double max_grown_radius(const LayoutParams& params) {
  double r = std::max(params.gate_radius_max, params.link_radius_max);
  for (const Character& c : params.characters) {
    r = std::max({r, c.small_radius_max, c.big_radius_max});
  }
  return r;
}

double max_room_radius(const LayoutParams& params) {
  double r = max_grown_radius(params);
  for (const Character& c : params.characters) {
    r = std::max(r, c.hall_radius_max);
  }
  return r;
}

double gate_edge_margin(const LayoutParams& p) {
  return (2.0 * p.gate_radius_max + p.wall_clearance) / std::sqrt(2.0);
}

double hall_clearance(const LayoutParams& p) {
  return 2.0 * p.gate_radius_max + p.wall_clearance + face_margin(p);
}

double face_margin(const LayoutParams& p) {
  return 0.5 * std::max(p.wall_clearance, p.portal_gap) + 0.25;
}

Status validate(const LayoutParams& p) {
  Checker check;
  check.finite_positive("sector_size", p.sector_size);
  check.int_range("gates_min", p.gates_min, 1, kMaxGatesPerFace);
  check.int_range("gates_max", p.gates_max, 1, kMaxGatesPerFace);
  check.ordered("gates_min", p.gates_min, "gates_max", p.gates_max);
  check.finite_positive("gate_radius_min", p.gate_radius_min);
  check.finite_positive("gate_radius_max", p.gate_radius_max);
  check.ordered("gate_radius_min", p.gate_radius_min, "gate_radius_max", p.gate_radius_max);
  check.finite_positive("link_radius_min", p.link_radius_min);
  check.finite_positive("link_radius_max", p.link_radius_max);
  check.ordered("link_radius_min", p.link_radius_min, "link_radius_max", p.link_radius_max);
  check.finite_positive("min_portal_radius", p.min_portal_radius);
  check.finite_positive("wall_clearance", p.wall_clearance);
  check.finite_positive("portal_gap", p.portal_gap);
  check.finite_positive("region_scale", p.region_scale);
  if (p.sector_size > kMaxSectorSize) {
    check.fail("sector_size must be at most " + number(kMaxSectorSize) + " metres (got " +
               number(p.sector_size) + ")");
  }
  if (!(p.region_scale >= 0.01 && p.region_scale <= 1e6)) {
    check.fail("region_scale must be in [0.01, 1e6] sectors (got " + number(p.region_scale) + ")");
  }
  if (p.portal_gap > 0.6 * p.link_radius_max) {
    check.fail("portal_gap (" + number(p.portal_gap) + ") must be at most 0.6 x link_radius_max (" +
               number(0.6 * p.link_radius_max) + "), or link rooms cannot join chains");
  }
  // Link portals are at most 0.45 of the smaller radius (sector.cpp), and must still fit a player.
  double link_portal = 0.45 * std::min(p.link_radius_min, p.gate_radius_min);
  if (p.min_portal_radius > link_portal) {
    check.fail("min_portal_radius (" + number(p.min_portal_radius) +
               ") must be at most 0.45 x min(link_radius_min, gate_radius_min) (" +
               number(link_portal) + "), or gates cannot be linked");
  }
  check.int_range("region_sharpness", p.region_sharpness, 0, 16);
  check.finite_positive("floor_min_radius", p.floor_min_radius);
  if (!(p.floor_depth >= 0 && p.floor_depth <= 0.9)) {
    check.fail("floor_depth must be in [0, 0.9] of the radius, 0 for no floors (got " +
               number(p.floor_depth) + ")");
  }
  if (!(p.ceiling_bend > 0 && p.ceiling_bend <= 1)) {
    check.fail("ceiling_bend must be in (0, 1] of the radius (got " + number(p.ceiling_bend) + ")");
  }
  if (!(p.ceiling_spring >= 0 && p.ceiling_spring + p.ceiling_bend <= 1)) {
    check.fail("ceiling_spring must be in [0, 1 - ceiling_bend] of the radius (got " +
               number(p.ceiling_spring) + ")");
  }
  if (!(p.ceiling_rise >= p.ceiling_spring + 0.5 * p.ceiling_bend)) {
    check.fail("ceiling_rise must be at least ceiling_spring + ceiling_bend / 2 (" +
               number(p.ceiling_spring + 0.5 * p.ceiling_bend) + "), >= 1 for no ceilings (got " +
               number(p.ceiling_rise) + ")");
  }
  // A floored room's portals open between its floor and its ceiling's spring: a player fits.
  double band = (p.floor_depth + p.ceiling_spring) * p.floor_min_radius - p.wall_clearance;
  if (p.ceiling_rise < 1 && std::isfinite(band) && band < 2.0 * p.min_portal_radius) {
    check.fail("floored rooms leave " + number(band) +
               " m between floor and ceiling_spring for portals, less than 2 x min_portal_radius" +
               " (raise floor_min_radius, floor_depth or ceiling_spring)");
  }
  for (int i = 0; i < kCharacterCount; ++i) {
    const Character& c = p.characters[i];
    std::string f = "characters[" + std::to_string(i) + "].";
    check.int_range(f + "room_count", c.room_count, 1, kMaxInteriorRooms / 2);
    check.int_range(f + "loops", c.loops, 0, kMaxInteriorRooms / 4);
    check.probability(f + "big_probability", c.big_probability);
    check.probability(f + "tunnel_chance", c.tunnel_chance);
    check.finite_positive(f + "small_radius_min", c.small_radius_min);
    check.finite_positive(f + "small_radius_max", c.small_radius_max);
    check.finite_positive(f + "big_radius_min", c.big_radius_min);
    check.finite_positive(f + "big_radius_max", c.big_radius_max);
    check.ordered(f + "small_radius_min", c.small_radius_min, f + "small_radius_max",
                  c.small_radius_max);
    check.ordered(f + "big_radius_min", c.big_radius_min, f + "big_radius_max", c.big_radius_max);
    check.probability(f + "hall_probability", c.hall_probability);
    check.finite_positive(f + "hall_radius_min", c.hall_radius_min);
    check.finite_positive(f + "hall_radius_max", c.hall_radius_max);
    check.ordered(f + "hall_radius_min", c.hall_radius_min, f + "hall_radius_max",
                  c.hall_radius_max);
    if (!is_finite(c.bias) || c.bias.x < 0 || c.bias.y < 0 || c.bias.z < 0 ||
        length_squared(c.bias) == 0) {
      check.fail(f + "bias must have finite, non-negative components, not all zero (got " +
                 number(c.bias.x) + ", " + number(c.bias.y) + ", " + number(c.bias.z) + ")");
    }
    if (c.small_radius_min < p.min_portal_radius || c.big_radius_min < p.min_portal_radius) {
      check.fail(f + "radii must be at least min_portal_radius (" + number(p.min_portal_radius) +
                 ") so that a player fits through portals");
    }
  }
  if (p.link_radius_min < p.min_portal_radius || p.gate_radius_min < p.min_portal_radius) {
    check.fail("gate and link radii must be at least min_portal_radius (" +
               number(p.min_portal_radius) + ")");
  }
  // Gates keep away from face edges by their radius plus the clearance, and a sector must leave
  // room in the middle for rooms of every size between its gates, and for its hall with a gate
  // and a link room between it and each face.
  double needed = 2.0 * gate_edge_margin(p) + 4.0 * max_grown_radius(p);
  if (std::isfinite(p.sector_size) && std::isfinite(needed) && p.sector_size < needed) {
    check.fail("sector_size (" + number(p.sector_size) + ") must be at least " + number(needed) +
               " for these radii (2 x the gates' edge margin + 4 x the largest radius)");
  }
  double hall_needed = 2.0 * (max_room_radius(p) + hall_clearance(p));
  if (std::isfinite(p.sector_size) && std::isfinite(hall_needed) && p.sector_size < hall_needed) {
    check.fail("sector_size (" + number(p.sector_size) + ") must be at least " +
               number(hall_needed) +
               " for these halls (2 x (the largest hall radius + a gate and a link room))");
  }
  return check.status();
}

int SectorCharacter::dominant() const {
  return static_cast<int>(std::max_element(weights.begin(), weights.end()) - weights.begin());
}

SectorCharacter sector_character(uint64_t seed, const LayoutParams& params, SectorCoord sector) {
  SectorCharacter out;
  double x = sector.x / params.region_scale, y = sector.y / params.region_scale,
         z = sector.z / params.region_scale;
  double sum = 0;
  for (int c = 0; c < kCharacterCount; ++c) {
    double v = value_noise(seed, c, x, y, z);
    double w = 1.0;
    for (int k = 0; k < params.region_sharpness; ++k)
      w *= v;
    out.weights[c] = w;
    sum += w;
  }
  for (double& w : out.weights)
    w = sum > 0 ? w / sum : 1.0 / kCharacterCount;

  const auto& cs = params.characters;
  auto mix = [&](auto field) {
    double v = 0;
    for (int c = 0; c < kCharacterCount; ++c)
      v += out.weights[c] * field(cs[c]);
    return v;
  };
  Character& b = out.blend;
  b.name = cs[out.dominant()].name;
  b.room_count = static_cast<int>(mix([](const Character& c) { return c.room_count; }) + 0.5);
  b.big_probability = mix([](const Character& c) { return c.big_probability; });
  b.small_radius_min = mix([](const Character& c) { return c.small_radius_min; });
  b.small_radius_max = mix([](const Character& c) { return c.small_radius_max; });
  b.big_radius_min = mix([](const Character& c) { return c.big_radius_min; });
  b.big_radius_max = mix([](const Character& c) { return c.big_radius_max; });
  b.bias = {mix([](const Character& c) { return c.bias.x; }),
            mix([](const Character& c) { return c.bias.y; }),
            mix([](const Character& c) { return c.bias.z; })};
  b.tunnel_chance = mix([](const Character& c) { return c.tunnel_chance; });
  b.loops = static_cast<int>(mix([](const Character& c) { return c.loops; }) + 0.5);
  b.hall_probability = mix([](const Character& c) { return c.hall_probability; });
  b.hall_radius_min = mix([](const Character& c) { return c.hall_radius_min; });
  b.hall_radius_max = mix([](const Character& c) { return c.hall_radius_max; });
  return out;
}

}  // namespace grotto::cave
