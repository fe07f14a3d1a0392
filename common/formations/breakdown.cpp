// Breakdown: the blocks fallen from a hall's ceiling, lying in piles on its floor.
//
// Big chambers are mostly breakdown chambers (Carlsbad's Big Room, Škocjan's Martel Chamber):
// as a ceiling spans wider, beds part along its bedding planes and fall as slabs and blocks, and
// the floor beneath the place where the ceiling broke is heaped with angular blocks, big ones
// near the middle of the heap and smaller ones round its edge, with the level floor between the
// heaps (E. L. White and W. B. White, "Breakdown", in Encyclopedia of Caves). Here: 1-3 heaps a
// hall, each under a point of its ceiling far from the portals, each of 10-40 blocks 0.3-4 m across
// whose sizes follow a truncated power law (a few big, many small), kept clear of the portals
// (passages stay open) and of the middle of the floor (where walkers cross the hall).
//
// Deterministic as the speleothems are: the room's own hashes (from its grid origin), the mesh's
// floats (candidate ceiling points sorted by position, not by vertex order) and a fixed order.
#include <algorithm>
#include <cmath>
#include <tuple>
#include <vector>

#include "common/formations/placer.hpp"
#include "common/relief/relief.hpp"

namespace grotto::formations::detail {
namespace {

// Halls: rooms whose sphere is at least this big (cave::LayoutParams::floor_min_radius's
// default: the rooms the mesh gives a floor and a low ceiling).
constexpr double kHallRadius = 12.0;
// A heap lies under a point of the ceiling facing down more than this, at least kHeapFromRim
// metres from every portal's rim, kHeapInner to kHeapOuter of the room's radius out from its
// axis (not over the middle of the floor, not against a wall), its blocks within its radius
// (kHeapRadiusMin metres to kHeapShare of the room's radius) of it.
constexpr float kCeilingDown = -0.7f;
constexpr float kHeapFromRim = 6.0f;
constexpr float kHeapInner = 0.4f;
constexpr float kHeapOuter = 0.72f;
constexpr float kHeapRadiusMin = 3.0f;
constexpr float kHeapShare = 0.3f;
// Blocks keep kBlockFromRim metres from every portal's rim and out of the middle kOpenMiddle of
// the room's radius.
constexpr float kBlockFromRim = 2.5f;
constexpr float kOpenMiddle = 0.25f;
// Sizes across (metres): a power law of exponent kSizeTail truncated to kSmallest-kLargest
// (over half the blocks over 0.5 m, one in four over 1 m, one in twelve over 2 m).
constexpr float kSmallest = 0.3f;
constexpr float kLargest = 4.0f;
constexpr float kSizeTail = 1.0f;
// A block stands on the floor round it: no deeper in it than this, and not in a wall or a bump
// higher than kBuried x its height (plus 10 cm) over its root.
constexpr float kMaxEmbed = 1.5f;
constexpr float kBuried = 0.6f;

// The room's hashes: from its grid origin (a quarter-metre lattice point: rooms lie metres
// apart), then a salt and an index, 0-1.
struct RoomHash {
  int room = 0;
  float operator()(int salt, int k) const { return relief::relief_hash(ivec3(room, salt, k)); }
};

RoomHash room_hash(Vec3 origin) {
  const ivec3 o(static_cast<int>(std::floor(origin.x * 4.0)),
                static_cast<int>(std::floor(origin.y * 4.0)),
                static_cast<int>(std::floor(origin.z * 4.0)));
  return {static_cast<int>(relief::relief_hash(o) * 16777216.0f)};
}

// A size across (metres) at share u of the truncated power law.
float block_size(float u) {
  const float floor_share = std::pow(kSmallest / kLargest, kSizeTail);
  return kSmallest / std::pow(1.0f - u * (1.0f - floor_share), 1.0f / kSizeTail);
}

// The nearest a portal's rim comes to a block (a vertical cylinder of its plan's radius from its
// bottom to its top's highest).
float from_rims(const std::vector<vec3>& rims, const FormationShape& f) {
  const float bottom = f.root.y - f.embed, top = f.root.y + f.length + f.taper * f.radius;
  float nearest = 1e30f;
  for (const vec3& p : rims) {
    const float across = std::max(length(vec2(p.x - f.root.x, p.z - f.root.z)) - f.radius, 0.0f);
    const float up = p.y > top ? p.y - top : p.y < bottom ? bottom - p.y : 0.0f;
    nearest = std::min(nearest, std::sqrt(across * across + up * up));
  }
  return nearest;
}

// Whether two blocks' plans lie apart: along the line between their axes, each plan's reach
// towards the other's (boulder_plan, in its own frame) adds up to less than the distance.
bool plans_apart(const FormationShape& a, const FormationShape& b) {
  const vec2 d = vec2(b.root.x - a.root.x, b.root.z - a.root.z);
  const float apart = length(d);
  if (apart > a.radius + b.radius) return true;
  const float towards = std::atan2(d.y, d.x);
  return apart > boulder_plan(a, towards - a.yaw) + boulder_plan(b, towards + 3.1415927f - b.yaw);
}

// Fits a block's bottom to the floor round it: the floor (the drawn surface) at 24 points on
// its plan's edge and 12 halfway in; the bottom reaches 10 cm (and 3 % of its radius, for the
// relief between the points) below the lowest. False where the floor ends (a portal's opening),
// where it falls away more than kMaxEmbed, or where it rises into the block (a wall, a bump) more
// than kBuried of its height.
bool fit_block(const Placer& placer, FormationShape& f) {
  const float margin = 0.1f + 0.03f * f.radius;
  float need = margin;
  for (int ring = 0; ring < 2; ++ring) {
    const int n = ring == 0 ? 24 : 12;
    for (int k = 0; k < n; ++k) {
      const float theta = 6.2831853f * static_cast<float>(k) / static_cast<float>(n);
      const float r = (ring == 0 ? 1.0f : 0.5f) * boulder_plan(f, theta);
      const vec2 at =
          vec2(f.root.x, f.root.z) + r * vec2(std::cos(theta + f.yaw), std::sin(theta + f.yaw));
      const float y = placer.height_near(at, f.root.y);
      if (std::isnan(y)) return false;
      if (y - f.root.y > kBuried * f.length + 0.1f) return false;
      need = std::max(need, f.root.y - y + margin);
    }
  }
  if (need > kMaxEmbed) return false;
  f.embed = need;
  return true;
}

}  // namespace

void place_breakdown(const Placer& placer, const Surface& s, std::vector<FormationShape>& out) {
  if (s.room_radius < kHallRadius) return;
  const float room = static_cast<float>(s.room_radius);
  const RoomHash hash = room_hash(s.origin);

  std::vector<vec3> rims;
  for (size_t v = 0; v < s.positions.size() && v < s.rim_portal.size(); ++v)
    if (s.rim_portal[v] >= 0) rims.push_back(placer.position(static_cast<uint32_t>(v)));
  auto from_rim = [&](vec3 p) {
    float nearest = 1e30f;
    for (const vec3& q : rims)
      nearest = std::min(nearest, distance(p, q));
    return nearest;
  };

  // The ceiling's candidates for a heap, by position (not by the decoder's vertex order).
  std::vector<vec3> ceiling;
  for (size_t v = 0; v < s.positions.size(); ++v) {
    if (v < s.rim_portal.size() && s.rim_portal[v] >= 0) continue;
    const vec3 p = placer.position(static_cast<uint32_t>(v));
    const float out_from_axis = length(vec2(p.x, p.z));
    if (!(placer.normal(static_cast<uint32_t>(v)).y < kCeilingDown) ||
        out_from_axis < kHeapInner * room || out_from_axis > kHeapOuter * room)
      continue;
    if (from_rim(p) < kHeapFromRim) continue;
    ceiling.push_back(p);
  }
  if (ceiling.empty()) return;
  std::sort(ceiling.begin(), ceiling.end(), [](const vec3& a, const vec3& b) {
    return std::tie(a.x, a.y, a.z) < std::tie(b.x, b.y, b.z);
  });

  struct Heap {
    vec2 centre{0.0f};
    float radius = 0;
    float ceiling = 0;  // the ceiling's height over it
    int count = 0;      // blocks wanted
  };
  std::vector<Heap> heaps;
  const int wanted = 1 + std::min(static_cast<int>(3.0f * hash(1, 0)), 2);
  for (int h = 0; h < wanted; ++h) {
    // 10-40 blocks a heap, at least 30 a hall; the heap as wide as they need (0.65-0.9 m of
    // radius per square root of a block: a third to half of its disc covered).
    const int count = std::max(10 + std::min(static_cast<int>(31.0f * hash(3, h)), 30),
                               (30 + wanted - 1) / wanted);
    for (int attempt = 0; attempt < 8; ++attempt) {
      const size_t at = std::min(
          static_cast<size_t>(hash(2, 8 * h + attempt) * static_cast<float>(ceiling.size())),
          ceiling.size() - 1);
      Heap heap;
      heap.centre = vec2(ceiling[at].x, ceiling[at].z);
      heap.ceiling = ceiling[at].y;
      heap.count = count;
      heap.radius = std::clamp(std::sqrt(static_cast<float>(count)) * mix(0.65f, 0.9f, hash(4, h)),
                               kHeapRadiusMin, kHeapShare * room);
      bool apart = true;
      for (const Heap& other : heaps)
        apart = apart && distance(heap.centre, other.centre) > heap.radius + other.radius;
      Hit ground;
      if (!apart || !placer.floor_under(heap.centre, heap.ceiling, ground)) continue;
      if (!(heap.ceiling - ground.y > 3.0f)) continue;  // a ceiling that low is a wall's overhang
      heaps.push_back(heap);
      break;
    }
  }

  std::vector<FormationShape> blocks;
  for (size_t h = 0; h < heaps.size(); ++h) {
    const Heap& heap = heaps[h];
    const int salt = 100 * static_cast<int>(h + 1);
    const int count = heap.count;
    // Their sizes first, the biggest placed first (nearest the middle: a slab falls straight
    // down, the pieces that break off it roll further), each tried at up to eight spots.
    struct Wanted {
      float size;
      int k;
    };
    std::vector<Wanted> sizes;
    for (int k = 0; k < count; ++k)
      sizes.push_back({block_size(hash(salt + 1, k)), k});
    std::sort(sizes.begin(), sizes.end(), [](const Wanted& a, const Wanted& b) {
      return a.size > b.size || (a.size == b.size && a.k < b.k);
    });
    for (const Wanted& want : sizes) {
      const int k = want.k;
      for (int attempt = 0; attempt < 8; ++attempt) {
        const int i = 8 * k + attempt;
        // Denser towards the middle (a share of the radius to the power 0.8, not 0.5).
        const float out_share = std::pow(hash(salt + 2, i), 0.8f);
        const float angle = 6.2831853f * hash(salt + 3, i);
        const vec2 xz =
            heap.centre + heap.radius * out_share * vec2(std::cos(angle), std::sin(angle));
        const float across =
            std::clamp(want.size * mix(1.5f, 0.7f, out_share), kSmallest, kLargest);
        FormationShape f{};
        f.kind = kFormationBoulder;
        f.radius = 0.5f * across;
        f.tip = mix(0.55f, 1.0f, hash(salt + 4, k));
        f.length = across * mix(0.28f, 0.5f, hash(salt + 5, k));
        f.taper = std::min(0.12f * hash(salt + 6, k), 0.3f * f.length / f.radius);
        f.flare = 6.2831853f * hash(salt + 7, k);
        f.rings = mix(0.04f, 0.1f, hash(salt + 8, k));
        f.bulbs = 0.2f * hash(salt + 9, k);
        f.seed = hash(salt + 10, k);
        f.yaw = 6.2831853f * hash(salt + 11, k);
        if (length(xz) - f.radius < kOpenMiddle * room) continue;
        // Apart from the blocks placed, and from the columns.
        bool apart = true;
        f.root = vec3(xz.x, 0.0f, xz.y);
        for (const FormationShape& b : blocks)
          apart = apart && plans_apart(f, b);
        for (const FormationShape& c : out)
          if (c.kind == kFormationColumn)
            apart = apart && distance(xz, vec2(c.root.x, c.root.z)) >
                                 f.radius + formation_bound_radius(c) + 0.1f;
        if (!apart) continue;
        // On the floor beneath the heap's ceiling, as a stalagmite's root is.
        Hit hit;
        if (!placer.floor_under(xz, heap.ceiling, hit)) continue;
        const SurfacePoint ground = placer.surface_at(hit, xz);
        if (!ground.clear || !(ground.normal.y > kFloor)) continue;
        f.root = vec3(xz.x, ground.position.y, xz.y);
        if (!fit_block(placer, f)) continue;
        if (from_rims(rims, f) < kBlockFromRim) continue;
        blocks.push_back(f);
        break;
      }
    }
  }
  if (blocks.empty()) return;

  // The stalagmites a block lies on are buried under it.
  std::erase_if(out, [&](const FormationShape& g) {
    if (g.kind != kFormationStalagmite) return false;
    for (const FormationShape& b : blocks)
      if (distance(vec2(g.root.x, g.root.z), vec2(b.root.x, b.root.z)) <
          b.radius + formation_bound_radius(g))
        return true;
    return false;
  });
  out.insert(out.end(), blocks.begin(), blocks.end());
}

}  // namespace grotto::formations::detail
