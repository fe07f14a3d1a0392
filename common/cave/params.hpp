// Layout parameters: the thesis's growing-tree knobs (§3.1.2) per kind of region, the sector
// scheme that makes the cave unbounded, and the smooth field that mixes regions over space.
#pragma once

#include <array>
#include <cstdint>
#include <string>

#include "common/cave/room_id.hpp"
#include "common/core/result.hpp"
#include "common/core/vec3.hpp"

namespace grotto::cave {

// One kind of region, described with the thesis's parameters (§3.1.2).
struct Character {
  std::string name;
  int room_count = 40;            // rooms grown per sector after the gates are linked
  double big_probability = 0.2;   // chance that a new room is big
  double small_radius_min = 2.5;  // metres
  double small_radius_max = 4.0;
  double big_radius_min = 6.0;
  double big_radius_max = 10.0;
  Vec3 bias{1.0, 0.3, 1.0};    // scales each axis of the random displacement direction
  double tunnel_chance = 0.5;  // chance to grow from the most recently added room
  int loops = 4;               // extra bridges between rooms near in space, far in the graph
  // Chance that a sector's hub, the room its gates are linked through, is a hall (a room of
  // hall_radius_min..max; the mesh keeps its sphere and gives it a floor) instead of a big room.
  double hall_probability = 0.0;
  double hall_radius_min = 10.0;
  double hall_radius_max = 14.0;
};

// The world every Grotto tool serves or shows when given no seed.
inline constexpr uint64_t kDefaultSeed = 7;

inline constexpr int kCharacterCount = 3;

struct LayoutParams {
  // Sectors are cubes of this edge (metres). Rooms of a sector stay inside it, so sectors can be
  // generated independently.
  double sector_size = 96.0;
  // Gate rooms per face between two sectors (inclusive range) and their radii.
  int gates_min = 1;
  int gates_max = 2;
  double gate_radius_min = 3.5;
  double gate_radius_max = 5.0;
  // Radius of the spheres that link gates into one connected sector.
  double link_radius_min = 3.0;
  double link_radius_max = 4.5;
  // A player must fit through every portal.
  double min_portal_radius = 1.2;
  // Spheres that do not overlap keep at least this gap, so room walls never cross.
  double wall_clearance = 1.0;
  // Portals of one room keep at least this gap along the sphere, room for wall between them.
  double portal_gap = 2.0;
  // Rooms at least floor_min_radius big have a floor floor_depth x radius below their centre
  // (the mesh rests the wall on it, mesh/deform_core.h): no portal of theirs opens below it
  // or within wall_clearance above it.
  double floor_min_radius = 12.0;
  double floor_depth = 0.2;
  // ... and a ceiling (cave::room_ceiling): their sphere keeps its wall up to ceiling_spring x
  // radius above the centre, then leans in over ceiling_bend x radius to a low dome whose top is
  // ceiling_rise x radius above the centre (a breakdown chamber's roof along a bedding plane, not
  // a planetarium). No portal of theirs opens above the spring. ceiling_rise >= 1: no ceiling.
  double ceiling_spring = 0.2;
  double ceiling_bend = 0.3;
  double ceiling_rise = 0.5;
  // Region field: characters change over about this many sectors.
  double region_scale = 4.0;
  // How sharply one character dominates a region: weights go as field^sharpness, so 0 makes
  // every sector an even mix and 8 gives crisp regions. An integer keeps libm out of the layout.
  int region_sharpness = 3;
  // The kinds of region the field mixes: by default narrow flat mazes, vertical shafts and
  // large caverns (thesis Figures 3-3 and 3-4).
  std::array<Character, kCharacterCount> characters = default_characters();

  static std::array<Character, kCharacterCount> default_characters();
  // Every sector uses `c` (the region field has nothing to mix): for experiments and tests.
  static LayoutParams uniform(const Character& c);
};

// Checks every field: finite numbers, positive radii, min <= max, counts in range, probabilities
// in [0, 1], a non-zero bias, and a sector large enough for its gates and rooms. The message names
// the offending field, e.g. "characters[1].big_radius_min must be > 0 (got -2)".
Status validate(const LayoutParams& params);

// The largest sphere radius any room can have under these parameters.
double max_room_radius(const LayoutParams& params);
// The same without halls: what the rooms grown and linked between gates and halls can have.
double max_grown_radius(const LayoutParams& params);

// How far gate centres keep from the edges of their face: gates on two faces that meet at an
// edge are then at least 2 x gate_radius_max + wall_clearance apart (the margin times sqrt 2).
double gate_edge_margin(const LayoutParams& params);

// How far interior rooms keep from their sector's faces: half of the larger of the wall
// clearance and the portal gap (plus a little for the angle test), so both rules hold across
// sector faces too.
double face_margin(const LayoutParams& params);

// How far a hall keeps from its sector's faces: a gate's width and the clearance, so a gate may
// sit anywhere on a face and a link room still fit between it and the hall.
double hall_clearance(const LayoutParams& params);

inline constexpr double kMaxSectorSize = 256.0;  // metres; bounds the work per sector

// The parameters in force in one sector: the characters blended by the region field.
struct SectorCharacter {
  std::array<double, kCharacterCount> weights{};  // sum to 1
  Character blend;                                // the weighted mix used to grow the sector
  int dominant() const;                           // index of the largest weight
};

SectorCharacter sector_character(uint64_t seed, const LayoutParams& params, SectorCoord sector);

}  // namespace grotto::cave
