#include "common/cave/geology.hpp"

#include <algorithm>
#include <cmath>

#include "common/core/detmath.hpp"
#include "common/core/random.hpp"

namespace grotto::cave {
namespace {

constexpr uint64_t kGeologyStream = 0x67656f6c6f6779ull;  // "geology"

// What each slowly varying field is for: one hash stream apiece.
enum Field : uint64_t {
  kStructure = 1,  // the beds' height field (their folds and dip)
  kStructureFine = 2,
  kDipAmount = 3,     // how steeply a region dips
  kBedStack = 4,      // the beds' thicknesses, a stack at a time
  kHardness = 5,      // each bed's hardness
  kJointStrikeX = 6,  // the first joint set's normal, a vector field
  kJointStrikeZ = 7,
  kJointTurn = 8,   // the second set's deviation from square
  kJointThird = 9,  // where a third set exists
  kJointSpacing = 10,
  kWaterLevel = 11,
  kLensField = 12,     // lens along the bedding, or a round tube (or a keyhole)
  kCanyonField = 13,   // vadose: canyon, or a bedding-plane passage or keyhole
  kFissureField = 14,  // where joints guide passages
  kAspectField = 15,   // how far a section departs from round
};

// Region scales (metres): beds fold over hundreds of metres, passage styles and the water's level
// change over a few passages, joints over a few sectors.
constexpr double kStructureCell = 420;
constexpr double kStructureFineCell = 150;
constexpr double kDipCell = 900;
constexpr double kJointCell = 600;
constexpr double kWaterCell = 40;
constexpr double kStyleCell = 50;
// Beds are laid out a stack of this many metres at a time (along the pole), 0.3-3 m each.
constexpr double kStackHeight = 24;
constexpr double kMinBed = 0.3, kMaxBed = 3.0;
constexpr int64_t kBedsPerStack = 128;  // > kStackHeight / kMinBed: bed numbers never collide

double unit_hash(uint64_t seed, uint64_t field, int64_t i, int64_t j) {
  uint64_t h =
      hash_words(seed, kGeologyStream, field, static_cast<uint64_t>(i), static_cast<uint64_t>(j));
  return static_cast<double>(h >> 11) * 0x1.0p-53;
}

// Value noise in [0, 1] on a square lattice of `cell` metres over (x, z), with its gradient per
// metre: smoothstep between hashed corners, so every field is C1 and position-independent (the
// same shape 6,000 km out: only the lattice numbers grow).
struct Field2 {
  double v = 0, dx = 0, dz = 0;
};
Field2 value2(uint64_t seed, uint64_t field, double x, double z, double cell) {
  const double fx = x / cell, fz = z / cell;
  const double ix = std::floor(fx), iz = std::floor(fz);
  const double tx = fx - ix, tz = fz - iz;
  const double sx = tx * tx * (3 - 2 * tx), sz = tz * tz * (3 - 2 * tz);
  const double dsx = 6 * tx * (1 - tx) / cell, dsz = 6 * tz * (1 - tz) / cell;
  const auto i = static_cast<int64_t>(ix), j = static_cast<int64_t>(iz);
  const double a = unit_hash(seed, field, i, j), b = unit_hash(seed, field, i + 1, j);
  const double c = unit_hash(seed, field, i, j + 1), d = unit_hash(seed, field, i + 1, j + 1);
  const double k = a - b - c + d;
  return {a + (b - a) * sx + (c - a) * sz + k * sx * sz, ((b - a) + k * sz) * dsx,
          ((c - a) + k * sx) * dsz};
}

Vec3 unit_or(Vec3 v, Vec3 fallback) {
  double len = length(v);
  return len > 1e-9 ? v / len : fallback;
}

// The bed holding pole coordinate s: the stack's beds drawn from one stream (thin beds more
// often than thick ones), the last one filling the stack.
void find_bed(uint64_t seed, double s, Geology& g) {
  const double stack = std::floor(s / kStackHeight);
  const double r = s - stack * kStackHeight;
  Rng rng(hash_words(seed, kGeologyStream, kBedStack, static_cast<uint64_t>(stack)));
  double base = 0;
  for (int64_t i = 0;; ++i) {
    double u = rng.uniform();
    double t = kMinBed + (kMaxBed - kMinBed) * u * u;
    // The last bed takes what is left (merged with this one when less than a bed would be).
    if (base + t + kMinBed > kStackHeight) t = kStackHeight - base;
    if (r < base + t) {
      g.bed = static_cast<int64_t>(stack) * kBedsPerStack + i;
      g.bed_thickness = t;
      g.bed_depth = std::clamp(r - base, 0.0, t);
      double hard = unit_hash(seed, kHardness, g.bed, 0);
      // Thick beds are mostly massive limestone; thin ones are often marly partings.
      g.bed_hardness =
          std::clamp(0.2 + 0.45 * hard + 0.35 * (t - kMinBed) / (kMaxBed - kMinBed), 0.0, 1.0);
      return;
    }
    base += t;
  }
}

// Beds: the level sets of y - h(x, z), h a folded height field whose amplitude varies by region
// (dips of a few degrees in most, up to about fifteen in some). h and its slopes at (x, z).
struct Structure {
  double h = 0, hx = 0, hz = 0;
};
Structure structure_at(uint64_t seed, Vec3 p) {
  Field2 amount = value2(seed, kDipAmount, p.x, p.z, kDipCell);
  Field2 broad = value2(seed, kStructure, p.x, p.z, kStructureCell);
  Field2 fine = value2(seed, kStructureFine, p.x, p.z, kStructureFineCell);
  const double amp = 10 + 80 * amount.v * amount.v;
  const double amp_dx = 160 * amount.v * amount.dx, amp_dz = 160 * amount.v * amount.dz;
  return {amp * (broad.v - 0.5) + 8 * (fine.v - 0.5),
          amp_dx * (broad.v - 0.5) + amp * broad.dx + 8 * fine.dx,
          amp_dz * (broad.v - 0.5) + amp * broad.dz + 8 * fine.dz};
}

}  // namespace

Geology geology_at(const World& world, Vec3 p) {
  const uint64_t seed = world.seed();
  Geology g;
  const Structure st = structure_at(seed, p);
  const double h = st.h, hx = st.hx, hz = st.hz;
  g.bedding_normal = unit_or(Vec3{-hx, 1, -hz}, Vec3{0, 1, 0});
  const double slope = std::sqrt(hx * hx + hz * hz);
  // atan without libm: the slope is small (below ~0.3), where this series is exact to 1e-5 rad.
  const double dip = slope - slope * slope * slope / 3 + slope * slope * slope * slope * slope / 5;
  g.dip_degrees = dip * 180 / detmath::kPi;
  find_bed(seed, p.y - h, g);

  // Joints: the first set's normal from a slowly turning horizontal vector field; the second
  // nearly square to it; a third, diagonal, in some regions. The planes are vertical.
  Field2 jx = value2(seed, kJointStrikeX, p.x, p.z, kJointCell);
  Field2 jz = value2(seed, kJointStrikeZ, p.x, p.z, kJointCell);
  const Vec3 first = unit_or(Vec3{jx.v - 0.5, 0, jz.v - 0.5}, Vec3{1, 0, 0});
  const Vec3 square{-first.z, 0, first.x};
  double turn_s, turn_c;
  detmath::sincos((value2(seed, kJointTurn, p.x, p.z, kJointCell).v - 0.5) * 0.5, turn_s, turn_c);
  const Vec3 second = square * turn_c + first * turn_s;
  Field2 spacing = value2(seed, kJointSpacing, p.x, p.z, kJointCell);
  g.joints[0] = {first, 0.5 + 1.5 * spacing.v};
  g.joints[1] = {second, 0.8 + 2.2 * (1 - spacing.v)};
  g.joint_count = 2;
  if (value2(seed, kJointThird, p.x, p.z, kJointCell).v > 0.6) {
    g.joints[2] = {unit_or(first + second, first), 1.5 + 2.5 * spacing.v};
    g.joint_count = 3;
  }

  // The water table: a level in every band of one sector's height (the cave has many storeys,
  // each with its own old water level), from 7 % to 77 % up the band and changing within tens of
  // metres (perched water and the levels of several stillstands), so that every part of the cave
  // has passages that formed full of water beside passages a stream cut.
  const double band_height = world.params().sector_size;
  const double band = std::floor(p.y / band_height);
  g.water_level =
      band_height * (band + 0.07 + 0.7 * value2(seed, kWaterLevel, p.x, p.z, kWaterCell).v);
  g.phreatic = p.y < g.water_level;
  return g;
}

std::vector<BedBreak> bed_breaks(const World& world, Vec3 p, double below, double above,
                                 double min_package, int max_breaks) {
  const uint64_t seed = world.seed();
  const Structure st = structure_at(seed, p);
  // Along the pole, s = y - h grows by `stretch` a metre (the planes through p).
  const double stretch = std::sqrt(st.hx * st.hx + 1 + st.hz * st.hz);
  const double s0 = p.y - st.h;
  std::vector<BedBreak> breaks;
  Geology g;
  find_bed(seed, s0 - below * stretch, g);
  double base = s0 - below * stretch - g.bed_depth;  // the first bed's base, in s
  double package_base = base;
  while (base < s0 + above * stretch) {
    find_bed(seed, base + 1e-6, g);  // the bed starting at base
    const double top = base + 1e-6 - g.bed_depth + g.bed_thickness;
    // A package ends where a bed starts once it is thick enough.
    if (top - package_base >= min_package * stretch) {
      const double offset = (top - s0) / stretch;
      if (offset > -below && offset < above) {
        Geology next;
        find_bed(seed, top + 1e-6, next);
        breaks.push_back({offset, next.bed_hardness});
      }
      package_base = top;
    }
    base = top;
  }
  // The nearest to the middle of the span, in order.
  const double middle = 0.5 * (above - below);
  while (static_cast<int>(breaks.size()) > max_breaks) {
    if (std::abs(breaks.front().offset - middle) > std::abs(breaks.back().offset - middle)) {
      breaks.erase(breaks.begin());
    } else {
      breaks.pop_back();
    }
  }
  return breaks;
}

const char* section_kind_name(SectionKind kind) {
  switch (kind) {
    case SectionKind::kTube:
      return "tube";
    case SectionKind::kLens:
      return "lens";
    case SectionKind::kCanyon:
      return "canyon";
    case SectionKind::kKeyhole:
      return "keyhole";
    case SectionKind::kFissure:
      return "fissure";
  }
  return "tube";
}

// 1 - the rim noise's amplitude (mesh params): how far the noise may narrow a section.
constexpr double kNoiseNarrowing = 0.88;

PassageSection passage_section(const World& world, Vec3 centre, Vec3 normal, double radius) {
  const uint64_t seed = world.seed();
  const Geology g = geology_at(world, centre);
  const Vec3 n = unit_or(normal, Vec3{0, 1, 0});
  // The narrowest a section's half-extent may be with the rim's noise at its narrowest: a player
  // 1.8 m tall walks through, and a walker 0.5 m in radius (the client's) with room for the
  // relief.
  constexpr double kMinHalfHeight = kMinClearHeight / 2, kMinHalfWidth = 0.6, kMinSlot = 0.42;
  const double r = radius * kNoiseNarrowing;
  const double min_width = std::min(1.0, kMinHalfWidth / r);
  const double min_height = std::min(1.0, kMinHalfHeight / r);
  const double style = value2(seed, kAspectField, centre.x, centre.z, kStyleCell).v;
  const auto narrow_to = [&](double aspect) { return std::max({min_width, 0.5, 1 / aspect}); };

  PassageSection s;
  const Vec3 world_up{0, 1, 0};
  const bool level = n.y * n.y <= 0.5;  // the passage runs within 45 degrees of level
  if (!level) {
    // A shaft: drawn out along the first joint set's strike where the joints guide it.
    const Vec3 strike{-g.joints[0].normal.z, 0, g.joints[0].normal.x};
    s.up = unit_or(strike - n * dot(strike, n), unit_or(cross(n, Vec3{1, 0, 0}), world_up));
    // No narrower than 0.62 of its disc: narrower ones folded the stitch between the rim and
    // the round hole in the room's donor sphere.
    s.half_width = std::max(0.62, narrow_to(1.0 + 1.3 * style));
    s.kind = s.half_width <= 0.67 ? SectionKind::kFissure : SectionKind::kTube;
    return s;
  }
  const Vec3 up_plumb = unit_or(world_up - n * dot(world_up, n), world_up);
  s.up = up_plumb;

  // Along a joint: the passage's axis lies in one of the joint planes.
  bool along_joint = false;
  for (int i = 0; i < g.joint_count; ++i) {
    if (std::abs(dot(n, g.joints[i].normal)) < 0.6) along_joint = true;
  }
  if (!g.phreatic && along_joint &&
      value2(seed, kFissureField, centre.x, centre.z, kStyleCell).v > 0.75) {
    s.kind = SectionKind::kFissure;
    s.half_width = narrow_to(2.0 + 0.6 * style);
    s.deepen = 1.0;
    return s;
  }
  // A lens along the bedding plane (the section's height tilted halfway to the beds' pole), no
  // lower than two thirds of its disc at its ends (a flatter one folded the stitch between its
  // rim and the round hole in the room's donor sphere), widening along the bed between them: a
  // small portal's lens is nearly round at its ends and wide in its middle.
  const double lens_field = value2(seed, kLensField, centre.x, centre.z, kStyleCell).v;
  const auto lens = [&] {
    const Vec3 pole = g.bedding_normal;
    const Vec3 up_bed = unit_or(pole - n * dot(pole, n), up_plumb);
    s.kind = SectionKind::kLens;
    s.up = unit_or(up_plumb + up_bed, up_plumb);
    s.half_height = std::min(1.0, std::max(min_height, 0.65 + 0.1 * style));
    s.widen = 1.4 + 0.3 * style;
    s.deepen = -0.3;  // ... and lower, where its ends are high enough to stay walkable
    return s;
  };
  if (g.phreatic) {
    // Dissolved full of water: along a soft bed that guided it, round where nothing did.
    if (lens_field > 0.15) return lens();
    s.kind = SectionKind::kTube;
    s.half_width = 0.92 + 0.08 * style;
    return s;
  }
  // Above the water table a stream cut down into the floor: a canyon (tall, narrow, a narrow flat
  // floor), or a keyhole (the tube it flowed in before, a slot below it to the floor); or it
  // spread along a soft bed instead of cutting down (a bedding-plane passage, low and wide).
  const double slot = std::min(0.45, std::max(0.3, kMinSlot / r));
  const double tube = 0.6 + 0.1 * style;
  const bool keyhole_fits = (tube + 0.95) * r >= 2 * kMinHalfHeight;
  const bool canyon = value2(seed, kCanyonField, centre.x, centre.z, kStyleCell).v > 0.45;
  if (!canyon && lens_field > 0.5) return lens();
  if (canyon || !keyhole_fits) {
    s.kind = SectionKind::kCanyon;
    s.half_width = narrow_to(1.9 + 0.6 * style);
    s.slot_depth = 0.95;
    s.slot_width = std::min(slot, s.half_width);
    s.deepen = 1.0;
    return s;
  }
  s.kind = SectionKind::kKeyhole;
  s.half_width = s.half_height = tube;
  s.slot_depth = 0.95;
  s.slot_width = slot;
  s.deepen = 1.0;
  return s;
}

double section_reach(const PassageSection& s) {
  double reach = std::max(s.half_width, s.half_height);
  if (s.slot_depth > 0) {
    reach = std::max(reach, std::sqrt(s.slot_depth * s.slot_depth + s.slot_width * s.slot_width));
  }
  return reach + 0.3;  // the smooth maximum's bias (deform_core.h's GROTTO_SECTION_SOFTNESS / 2)
}

double section_clear_height(const PassageSection& s, double radius) {
  return radius * kNoiseNarrowing * (s.half_height + std::max(s.half_height, s.slot_depth));
}

double section_narrow(const PassageSection& s) {
  return std::min(s.half_width, s.half_height);
}

double section_aspect(const PassageSection& s) {
  const double below = std::max(s.half_height, s.slot_depth);
  return (s.half_height + below) / (2 * std::max(s.half_width, s.slot_width));
}

double section_perimeter(const PassageSection& s) {
  // Ramanujan's approximation of the ellipse's perimeter, plus the slot's sides below it.
  const double a = s.half_width, b = s.half_height;
  double p = detmath::kPi * (3 * (a + b) - std::sqrt((3 * a + b) * (a + 3 * b)));
  if (s.slot_depth > b) p += 2 * (s.slot_depth - b);
  return p / (2 * detmath::kPi);
}

}  // namespace grotto::cave
