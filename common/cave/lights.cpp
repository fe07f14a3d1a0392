#include "common/cave/lights.hpp"

#include <algorithm>
#include <cmath>
#include <optional>

#include "common/core/random.hpp"

namespace grotto::cave {
namespace {

constexpr uint64_t kLightStream = 0x6c69676874000001ull;  // "light": a room's lights
// Candidate positions tried per light before it is given up (a light is dropped, never moved
// somewhere arbitrary); halls try more so that they keep at least hall_min.
constexpr int kTries = 24;
constexpr int kHallTries = 96;

// A uniform direction: rejection from the cube (Marsaglia-style), normalized with sqrt only.
Vec3 random_direction(Rng& rng) {
  for (;;) {
    const Vec3 v{rng.uniform(-1, 1), rng.uniform(-1, 1), rng.uniform(-1, 1)};
    const double l2 = length_squared(v);
    if (l2 > 1e-4 && l2 <= 1) return v / std::sqrt(l2);
  }
}

// Colours of real glowing things, linear RGB: Arachnocampa's blue-green (~490 nm), willemite's
// green and calcite's orange fluorescence for seams, fluorite's violet and a cold cyan for
// crystals.
Vec3 pick_colour(LightKind kind, Rng& rng) {
  switch (kind) {
    case LightKind::kGlowWorms:
      return {0.30, 0.80 + 0.1 * rng.uniform(), 1.0};
    case LightKind::kMineralSeam:
      return rng.chance(0.6) ? Vec3{0.35, 1.0, 0.30} : Vec3{1.0, 0.45, 0.15};
    case LightKind::kCrystals:
      return rng.chance(0.5) ? Vec3{0.65, 0.35, 1.0} : Vec3{0.35, 0.85, 1.0};
  }
  return {1, 1, 1};
}

LightKind pick_kind(Rng& rng, bool has_floor) {
  const double u = rng.uniform();
  if (u < 0.4) return LightKind::kGlowWorms;
  if (u < (has_floor ? 0.7 : 0.8)) return LightKind::kMineralSeam;
  return LightKind::kCrystals;
}

struct Candidate {
  Vec3 position;
  Vec3 facing;
};

// Where a light of this kind could sit: glow-worms on the ceiling's cap, seams on the walls,
// crystals on the floor (or low on the wall of a room without one).
Candidate candidate(LightKind kind, const Room& room, std::optional<double> floor,
                    const std::optional<Ceiling>& ceiling, const LightParams& p, Rng& rng) {
  const Vec3 c = room.sphere.centre;
  const double r = room.sphere.radius;
  Vec3 d = random_direction(rng);
  switch (kind) {
    case LightKind::kGlowWorms:
      // The upper cap, |d.y| >= 0.45 (within ~63 degrees of straight up).
      d.y = 0.45 + 0.55 * std::max(d.y, -d.y);
      break;
    case LightKind::kMineralSeam:
      d.y *= 0.35;
      break;
    case LightKind::kCrystals:
      if (floor) {
        // On the floor, out towards the wall: the floor's disc has radius ~0.98 r (floor_depth
        // 0.2).
        const double h = std::sqrt(d.x * d.x + d.z * d.z);
        const double out = rng.uniform(0.5, 0.8) * r;
        if (h < 1e-6) return {c, Vec3{0, 1, 0}};
        const Vec3 at{c.x + d.x / h * out, *floor + p.floor_lift, c.z + d.z / h * out};
        return {at, Vec3{0, 1, 0}};
      }
      d.y = -(0.2 + 0.4 * std::max(d.y, -d.y));
      break;
  }
  d = normalize(d);
  Vec3 at = c + d * (p.wall_fraction * r);
  // Under a hall's low dome, on it: the wall there is lowered as the mesh lowers it.
  if (ceiling) at.y = ceiling->lower(at.y);
  return {at, -d};
}

bool acceptable(const Candidate& k, const Room& room, std::optional<double> floor,
                const LightParams& p, const std::vector<WorldLight>& placed) {
  if (!in_space(room, k.position)) return false;
  if (floor && k.position.y < *floor + p.floor_lift) return false;
  for (const Portal& portal : room.portals)
    if (distance(k.position, portal.centre) < portal.radius + p.portal_clearance) return false;
  // Spread out: no two lights of a room closer than a third of its radius.
  const double spread = room.sphere.radius / 3;
  for (const WorldLight& l : placed)
    if (length_squared(l.position - k.position) < spread * spread) return false;
  return true;
}

}  // namespace

const char* light_kind_name(LightKind kind) {
  switch (kind) {
    case LightKind::kGlowWorms:
      return "glow_worms";
    case LightKind::kMineralSeam:
      return "mineral_seam";
    case LightKind::kCrystals:
      return "crystals";
  }
  return "unknown";
}

double light_source_radius(const WorldLight& light) {
  if (light.kind == LightKind::kGlowWorms) return std::max(light.size, 1.0);
  return std::max(kSourceRadiusPerRange * light.range, 1.0);
}

double light_falloff(const WorldLight& light, double d) {
  if (light.range <= 0 || d >= light.range) return 0;
  const double x = d / light.range;
  const double window = std::clamp(1 - x * x * x * x, 0.0, 1.0);
  const double r = light_source_radius(light);
  return window * window / (r * r + d * d);
}

double light_bound_radius(const Room& room) {
  constexpr double kScale = 1.1;
  constexpr double kMargin = 1.5;  // metres
  return kScale * room.sphere.radius + kMargin;
}

float light_pattern_seed(Vec3 p) {
  const uint64_t h = hash_words(0x6c69676874ull, static_cast<uint64_t>(std::llround(p.x * 1000.0)),
                                static_cast<uint64_t>(std::llround(p.y * 1000.0)),
                                static_cast<uint64_t>(std::llround(p.z * 1000.0)));
  return static_cast<float>(h >> 40) / 16777216.0f;
}

std::vector<WorldLight> room_lights(uint64_t seed, const LayoutParams& layout, const Room& room,
                                    const LightParams& p) {
  Rng rng(hash_words(seed, kLightStream, room.id.packed()));
  const std::optional<double> floor = floor_height(layout, room.sphere);
  const std::optional<Ceiling> ceiling = room_ceiling(layout, room.sphere);
  const double r = room.sphere.radius;
  int count = 0;
  if (floor) {
    count = p.hall_min + static_cast<int>(rng.below(
                             static_cast<uint32_t>(std::max(p.hall_max - p.hall_min + 1, 1))));
  } else if (rng.chance(r >= p.big_radius ? p.big_chance : p.small_chance)) {
    count = 1;
  }
  std::vector<WorldLight> out;
  const int tries = floor ? kHallTries : kTries;
  for (int i = 0; i < count; ++i) {
    // Each light draws from a stream of its own: a light given up does not shift the next.
    Rng lr(hash_combine(rng.next_u64(), static_cast<uint64_t>(i)));
    const LightKind kind = pick_kind(lr, floor.has_value());
    for (int t = 0; t < tries; ++t) {
      const Candidate k = candidate(kind, room, floor, ceiling, p, lr);
      if (!acceptable(k, room, floor, p, out)) continue;
      WorldLight l;
      l.kind = kind;
      l.position = k.position;
      l.facing = k.facing;
      l.colour = pick_colour(kind, lr);
      l.range = std::max(p.min_range, p.range_per_radius * r);
      // Glow-worms are faint (each a pinprick; a colony lights by its numbers): a third of a
      // mineral's light, so a colony overhead reads as a starry ceiling, not a lamp.
      const double faint = kind == LightKind::kGlowWorms ? 0.35 : 1.0;
      l.intensity = faint * p.intensity_per_range2 * l.range * l.range * lr.uniform(0.7, 1.3);
      switch (kind) {
        case LightKind::kGlowWorms:
          l.size = std::clamp(0.15 * r, 1.0, 3.0);
          break;
        case LightKind::kMineralSeam:
          l.size = std::clamp(0.1 * r, 0.8, 2.0);
          break;
        case LightKind::kCrystals:
          l.size = lr.uniform(0.5, 1.0);
          break;
      }
      out.push_back(l);
      break;
    }
  }
  return out;
}

}  // namespace grotto::cave
