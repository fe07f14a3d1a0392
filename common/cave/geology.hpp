// The rock a world is cut in: beds with a regional dip, some harder than others; two or three
// steep joint sets; and the water table's level, phreatic below and vadose above. One pure function
// of (world, position) that varies slowly from region to region (a few hundred metres), and the
// passage section it gives a portal: a lens along the bedding, a canyon or a keyhole cut into the
// floor above the water table, a fissure along a joint, or a round tube.
//
// Part of the world definition: proto::world_params_digest folds kGeologyVersion. The room meshes
// read it (their portals' sections); engines and the glb export read it too. Deterministic like
// the layout: Grotto's own hash, only +, -, *, / and sqrt (no libm), no state.
#pragma once

#include <array>
#include <cstdint>
#include <vector>

#include "common/cave/layout.hpp"
#include "common/core/vec3.hpp"

namespace grotto::cave {

// Bumped whenever the geology or the sections it gives change: part of the world digest.
inline constexpr const char* kGeologyVersion = "grotto.geology.v3";

// One set of parallel fractures: steep planes `spacing` metres apart.
struct JointSet {
  Vec3 normal;         // unit, nearly horizontal (the planes are steep)
  double spacing = 1;  // metres between planes
};

struct Geology {
  Vec3 bedding_normal{0, 1, 0};  // the beds' pole: unit, upward; tilted by the regional dip
  double dip_degrees = 0;        // the beds' dip from horizontal
  int64_t bed = 0;               // which bed holds the point (counted upwards along the pole)
  double bed_thickness = 1;      // metres, 0.3-3
  double bed_hardness = 0.5;     // 0 soft (shale, marly beds) to 1 hard (massive limestone)
  double bed_depth = 0;          // metres from the bed's base up to the point, in [0, thickness)
  std::array<JointSet, 3> joints{};
  int joint_count = 2;     // 2 or 3
  double water_level = 0;  // world y of the water table's level governing the point
  bool phreatic = false;   // below water_level: passages formed full of water
};

// The rock at `p` (world metres). Pure: the same for every caller, any order, any machine.
Geology geology_at(const World& world, Vec3 p);

// A break between packages of beds along the pole through a point: where a hall's ceiling steps
// (a slab's underside) and its walls change from one package to the next.
struct BedBreak {
  double offset = 0;    // metres along the beds' pole from the point (negative: below)
  double hardness = 0;  // 0-1: the package above it (soft packages weather back into notches)
};

// The breaks between packages of beds at least `min_package` metres thick (thinner beds merge
// into the package above them) within `below` metres under and `above` metres over `p` along
// the pole there, in order (at most `max_breaks`, the nearest to the middle of the span kept),
// from the same beds geology_at gives, taken as planes through p (a hall's span is small against
// the folds).
std::vector<BedBreak> bed_breaks(const World& world, Vec3 p, double below, double above,
                                 double min_package, int max_breaks);

// How a passage formed, read off its section.
enum class SectionKind : uint8_t {
  kTube = 0,     // round: phreatic, no guiding bed or joint
  kLens = 1,     // phreatic, along a bedding plane: wider than tall
  kCanyon = 2,   // vadose: cut down by a stream, tall and narrow with a narrow floor
  kKeyhole = 3,  // a phreatic tube with a vadose slot cut below it
  kFissure = 4,  // along a joint: tall and narrow
};
const char* section_kind_name(SectionKind kind);

// A portal's section, inside its disc: an ellipse of half-width half_width * radius and
// half-height half_height * radius (each at most one, so the openings of one room do not run into
// each other), its height along `up`; and below the centre
// a slot of half-width slot_width * radius whose flat floor lies slot_depth * radius below the
// centre (a canyon's or keyhole's floor; slot_depth 0: none). The same for both rooms.
struct PassageSection {
  SectionKind kind = SectionKind::kTube;
  Vec3 up{0, 1, 0};  // unit, in the portal's plane: the section's height
  double half_width = 1;
  double half_height = 1;
  double slot_depth = 0;
  double slot_width = 0;
  // How a passage that formed here grows between its two ends, as a fraction of its section
  // there: a lens widens along its bed (and lowers, where its ends are high enough to stay
  // walkable) and a canyon or fissure grows taller, most halfway along. Its portals are its
  // narrowest places, as a cave's squeezes lie between its rooms. A passage grows as the section
  // at its middle says (mesh/room_mesh.cpp's set_growth keeps it inside its room's sphere and
  // walkable).
  double widen = 0;
  double deepen = 0;
};

// The clear height every section leaves (metres): a player 1.8 m tall walks through.
inline constexpr double kMinClearHeight = 2.0;

// The section of a portal at `centre` with unit `normal` (either sign: the section does not
// depend on it) and disc radius `radius`, from the geology at its centre and the passage's
// direction. Every section keeps a player 1.8 m tall and 1 m wide walking through with the
// rim's noise at its narrowest.
PassageSection passage_section(const World& world, Vec3 centre, Vec3 normal, double radius);
// The farthest any section reaches from its portal's centre, in radii (the slot's corners and
// the smooth join of slot and ellipse reach a little past the disc).
inline constexpr double kMaxSectionReach = 1.35;

// The section's extent in radii (the shape itself is evaluated where the rims are built,
// common/mesh/deform_core.h's grotto_section): the farthest it reaches from the centre (the
// rim's noise fade), the nearest (how far the rim's noise may narrow it), its overall height
// over its width, and its perimeter over 2 pi (how many vertices its rim gets).
double section_reach(const PassageSection& section);
double section_narrow(const PassageSection& section);
double section_aspect(const PassageSection& section);
double section_perimeter(const PassageSection& section);
// Its clear height in metres for a disc of `radius`, with the rim's noise at its narrowest.
double section_clear_height(const PassageSection& section, double radius);

}  // namespace grotto::cave
