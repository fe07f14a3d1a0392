// Mesh parameters per level of detail (thesis §3.1.3-3.1.6 and §5.5).
#pragma once

#include <array>
#include <cstdint>

#include "common/core/result.hpp"
#include "common/mesh/deform.hpp"

namespace grotto::mesh {

// detail: the thesis's density and 4 noise octaves. patch: about 20% of the vertices and 3
// octaves, the mesh that is streamed and tessellated on the GPU (§5.5).
enum class Lod : uint8_t { kDetail = 0, kPatch = 1 };
inline constexpr int kLodCount = 2;
const char* lod_name(Lod lod);

// The noise lattice repeats every 256 cells; world positions are sampled modulo kNoisePeriod
// (mesh/context.hpp: 16,384 m). A frequency f gives a seamless wrap when kNoisePeriod * f is a
// multiple of 256, i.e. when f is a multiple of this step (cycles per metre).
inline constexpr double kNoiseFrequencyStep = 1.0 / 64.0;

struct LodParams {
  double edge_length;  // target edge of the donor sphere and of rim loops, metres
  int octaves;         // surface noise octaves used (of MeshParams::octave_*)
  // The donor sphere's frequency is at most this (10 f^2 + 2 vertices): a hall's mesh gets
  // longer edges instead of more vertices, so its payload and its cost stay within the
  // streaming budgets (the patch level's 24: 5,762 vertices before the portals are cut, edges of
  // ~1.1 m in a 25 m hall; the GPU's tessellation adds the detail). A hall is the first room of
  // many players, and its encode and decode cost by the vertex: 28 (7,842) doubled the p99 of a
  // crowd joining over 2 s (docs/BENCHMARKS.md, "Capacity with the defaults").
  int max_frequency;
};

struct MeshParams {
  std::array<LodParams, kLodCount> lods{{{0.25, 4, 64}, {0.56, 3, 24}}};
  // Every frequency (cycles per metre) is a multiple of kNoiseFrequencyStep, so that noise repeats
  // exactly over the noise period and the wrap of world positions leaves no seam (validate()).
  // Surface noise octaves (thesis §3.1.6): cycles per metre and metres of displacement.
  std::array<double, GROTTO_MAX_OCTAVES> octave_frequency{10 / 64.0, 19 / 64.0,  38 / 64.0,
                                                          77 / 64.0, 154 / 64.0, 307 / 64.0};
  std::array<double, GROTTO_MAX_OCTAVES> octave_amplitude{0.45, 0.22, 0.11, 0.06, 0.03, 0.015};
  double rim_frequency = 22 / 64.0;  // irregular rims: noise on the portal radius ...
  double rim_amplitude = 0.12;       // ... as a fraction of the radius
  // Surface noise fades in over this distance from a portal plane's extension beyond the disc,
  // so that no vertex crosses a plane; at the disc the noise runs into the rim instead.
  double fade_distance = 1.2;
  // At a portal the rim moves with the surface noise (deform_core.h, grotto_rim_noise), but
  // narrows it no further than this radius (metres; the layout's narrowest portal, 1.2 m, with
  // its irregular rim, is 1.06 m) and eases into that limit over rim_softness metres.
  double rim_min_radius = 1.05;
  double rim_softness = 0.1;
  // The low-frequency octave of large rooms, faded out near portals (thesis §3.1.6).
  double big_room_radius = 6.0;  // rooms at least this big get it
  double big_frequency = 4 / 64.0;
  double big_amplitude = 0.12;  // fraction of the room radius
  double big_fade_distance = 5.0;
  double roundness = 0.35;  // 0: the thesis's tubes; 1: rooms keep their sphere
  // The same for small rooms (below big_room_radius) whose two portals face each other across
  // the room (normals within ~60 degrees of opposite, fully from ~30): straight passage.
  double passage_roundness = 0.1;
  double tension = 1.0;  // Hermite tangent length, fraction of the span between rims
  // Near a portal's axis line the spline's rim point is pulled towards the disc centre, within
  // this many edges of the level of detail (at most half the portal's radius); 0: off.
  double axis_fade_edges = 4.0;
  // Big rooms keep their sphere beyond this height above every portal plane (metres), with
  // their noise held within wall_allow metres outside it (eased over wall_softness metres).
  double keep_distance = 2.5;
  double wall_allow = 0.4;
  double wall_softness = 0.5;
  // Rooms with a floor (cave::floor_height: the layout places floors) rest their wall on an
  // undulating plane: floor_amplitude metres of noise at floor_frequency cycles per metre.
  double floor_amplitude = 0.25;
  double floor_frequency = 8 / 64.0;
  // Roughness and mineral fields (per-vertex channels that steer GPU detail).
  double roughness_frequency = 5 / 64.0;  // a second octave at 3x
  double mineral_frequency = 7 / 64.0;
};

// Checks ranges; names the field in the message.
Status validate(const MeshParams& params);

// The device-facing shape for one level of detail.
core::GrottoShape shape_for(const MeshParams& params, Lod lod);

}  // namespace grotto::mesh
