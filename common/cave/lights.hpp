// Light in the dark: the light sources the world places in its rooms, as a pure
// function of (seed, parameters, room). Glow-worm colonies hang on ceilings; glowing mineral seams
// and crystal clusters sit on walls and floors. Halls (rooms with a floor) get a few each; other
// rooms rarely get one, so most passages stay dark and a lit hall reads as a landmark (Deep Rock
// Galactic's glowing life; Waitomo's glow-worm grottos).
//
// Part of the world definition: proto::world_params_digest folds kLightsVersion and LightParams,
// and engines call room_lights to get the same lights the client draws (docs/INTEGRATION.md).
// Deterministic like the layout: Grotto's own hash and Rng, only +, -, *, / and sqrt (no libm),
// one Rng stream per (seed, room), so a room's lights never depend on which other rooms were
// asked for, or in which order.
#pragma once

#include <cstdint>
#include <vector>

#include "common/cave/layout.hpp"
#include "common/cave/params.hpp"
#include "common/core/vec3.hpp"

namespace grotto::cave {

// Bumped whenever placement, kinds or colours change: part of the world digest.
inline constexpr const char* kLightsVersion = "grotto.lights.v2";

enum class LightKind : uint8_t {
  kGlowWorms = 0,    // a colony of blue-green dots on a ceiling
  kMineralSeam = 1,  // a glowing vein in a wall
  kCrystals = 2,     // a cluster of glowing crystals on a floor or low on a wall
};
inline constexpr int kLightKindCount = 3;
// "glow_worms", "mineral_seam", "crystals": the names reports and glTF extras use.
const char* light_kind_name(LightKind kind);

// A light. Shading convention (shaders/lights.glsl and what an engine should match): the
// radiance reaching a point at distance d is colour * intensity * light_falloff(light, d):
// 1 / (r^2 + d^2) for a source of radius r = light_source_radius(light), windowed to zero at
// `range` by (1 - (d / range)^4)^2 (Karis, "Real Shading in Unreal Engine 4", 2013).
struct WorldLight {
  LightKind kind = LightKind::kGlowWorms;
  Vec3 position;  // world metres: inside the room's space, above its floor
  Vec3 facing;    // unit: from the rock it grows on into the room
  Vec3 colour;    // linear RGB, largest component 1
  double intensity = 0;
  double range = 0;  // metres: where its light reaches zero
  double size = 0;   // metres: radius of the glowing patch of rock around it
};

struct LightParams {
  // Halls: a uniform count in [hall_min, hall_max].
  int hall_min = 3;
  int hall_max = 6;
  // Rooms without a floor: one light with this chance (big rooms, radius >= big_radius, with
  // big_chance; the rest with small_chance).
  double big_radius = 6.0;
  double big_chance = 0.3;
  double small_chance = 0.05;
  // How far out along the radius a light sits: on or just inside the wall.
  double wall_fraction = 0.88;
  // Lights keep this many metres beyond a portal's radius from its centre (a portal is no wall).
  double portal_clearance = 1.5;
  // Floor crystals sit this far above the floor (its relief is up to ~0.25 m, mesh params).
  double floor_lift = 0.45;
  // Range: range_per_radius x the room's radius, at least min_range.
  double range_per_radius = 1.4;
  double min_range = 8.0;
  // Intensity at 1 m is intensity_per_range2 x range^2, so a light's far edge is lit alike in
  // any room size.
  double intensity_per_range2 = 0.06;
};

// How wide a light's source is, in metres (the r of 1 / (r^2 + d^2)). A glow-worm colony is an
// area of pinpricks: max(size, 1). A seam or a crystal cluster bright enough to light a hall to
// its far wall is a source metres across: kSourceRadiusPerRange x range, at least 1 m, so the rock
// beside it is lit as a wall a few metres from a point would be, not burnt white, while the far
// wall keeps its light (at 20 m in a hall lit to 40 m: 92 % of what a point source gives).
inline constexpr double kSourceRadiusPerRange = 0.15;
double light_source_radius(const WorldLight& light);

// The share of colour * intensity that reaches distance d (metres) from the light: the shading
// convention above, in one function (collision-free gameplay light levels, engines, tests).
double light_falloff(const WorldLight& light, double d);

// The sphere a light of `room` lights rock within: the room's sphere grown by a tenth and 1.5 m
// (the relief and the rim noise reach out of the sphere; a hall keeps its sphere). The rock
// between rooms casts no shadow in the shader, so this bound keeps a light from shining through
// into the next room. Flares use the bound of the room they burn in.
double light_bound_radius(const Room& room);

// A light's own number in [0, 1), from where it is (to the millimetre): the same in every frame
// wherever the camera is; it orients a seam's vein and phases a colony's dots
// (shaders/lights.glsl's u_light_glow.z).
float light_pattern_seed(Vec3 position);

// The room's lights, in the order they were drawn (deterministic). Any room of the world with
// its portals (cave::room); `layout` gives its floor (floor_height). Lights keep clear of every
// portal and lie inside cave::in_space(room, position) and above the floor.
std::vector<WorldLight> room_lights(uint64_t seed, const LayoutParams& layout, const Room& room,
                                    const LightParams& params = {});

}  // namespace grotto::cave
