#include "common/mesh/params.hpp"

#include <cmath>
#include <string>

namespace grotto::mesh {
namespace {

bool positive(double v) {
  return std::isfinite(v) && v > 0;
}
// A positive multiple of kNoiseFrequencyStep (exact: such values are binary fractions).
bool noise_frequency(double v) {
  return positive(v) && v <= 64.0 && std::floor(v / kNoiseFrequencyStep) * kNoiseFrequencyStep == v;
}
constexpr const char* kFrequencyRule =
    "a multiple of 1/64 in (0, 64] cycles per metre (noise wraps seamlessly only then)";
bool non_negative(double v) {
  return std::isfinite(v) && v >= 0;
}

}  // namespace

const char* lod_name(Lod lod) {
  return lod == Lod::kDetail ? "detail" : "patch";
}

Status validate(const MeshParams& p) {
  auto bad = [](const std::string& field, double v, const char* rule) {
    return invalid_argument("invalid mesh parameters: " + field + " must be " + rule + " (got " +
                            std::to_string(v) + ")");
  };
  for (int l = 0; l < kLodCount; ++l) {
    std::string f = std::string("lods[") + lod_name(static_cast<Lod>(l)) + "].";
    if (!(p.lods[l].edge_length >= 0.05 && p.lods[l].edge_length <= 5.0)) {
      return bad(f + "edge_length", p.lods[l].edge_length, "in [0.05, 5] metres");
    }
    if (p.lods[l].octaves < 0 || p.lods[l].octaves > GROTTO_MAX_OCTAVES) {
      return bad(f + "octaves", p.lods[l].octaves, "in [0, 6]");
    }
    if (p.lods[l].max_frequency < 2 || p.lods[l].max_frequency > 80) {
      return bad(f + "max_frequency", p.lods[l].max_frequency,
                 "in [2, 80] (80: 64,002 vertices, the codec's ceiling)");
    }
  }
  for (int k = 0; k < GROTTO_MAX_OCTAVES; ++k) {
    if (!noise_frequency(p.octave_frequency[k])) {
      return bad("octave_frequency[" + std::to_string(k) + "]", p.octave_frequency[k],
                 kFrequencyRule);
    }
    if (!non_negative(p.octave_amplitude[k])) {
      return bad("octave_amplitude[" + std::to_string(k) + "]", p.octave_amplitude[k], ">= 0");
    }
  }
  if (!noise_frequency(p.rim_frequency)) {
    return bad("rim_frequency", p.rim_frequency, kFrequencyRule);
  }
  if (!(p.rim_amplitude >= 0 && p.rim_amplitude <= 0.3)) {
    return bad("rim_amplitude", p.rim_amplitude, "in [0, 0.3]");
  }
  if (!positive(p.fade_distance)) return bad("fade_distance", p.fade_distance, "> 0");
  if (!non_negative(p.rim_min_radius)) return bad("rim_min_radius", p.rim_min_radius, ">= 0");
  if (!positive(p.rim_softness)) return bad("rim_softness", p.rim_softness, "> 0");
  if (!positive(p.big_room_radius)) return bad("big_room_radius", p.big_room_radius, "> 0");
  if (!noise_frequency(p.big_frequency)) {
    return bad("big_frequency", p.big_frequency, kFrequencyRule);
  }
  if (!(p.big_amplitude >= 0 && p.big_amplitude <= 0.5)) {
    return bad("big_amplitude", p.big_amplitude, "in [0, 0.5]");
  }
  if (!positive(p.big_fade_distance)) {
    return bad("big_fade_distance", p.big_fade_distance, "> 0");
  }
  if (!(p.roundness >= 0 && p.roundness <= 1)) return bad("roundness", p.roundness, "in [0, 1]");
  if (!(p.passage_roundness >= 0 && p.passage_roundness <= 1)) {
    return bad("passage_roundness", p.passage_roundness, "in [0, 1]");
  }
  if (!(p.tension > 0 && p.tension <= 3)) return bad("tension", p.tension, "in (0, 3]");
  if (!(p.axis_fade_edges >= 0 && p.axis_fade_edges <= 16)) {
    return bad("axis_fade_edges", p.axis_fade_edges, "in [0, 16]");
  }
  if (!(p.keep_distance >= 0 && p.keep_distance <= 20)) {
    return bad("keep_distance", p.keep_distance, "in (0, 20] metres");
  }
  if (!(p.wall_allow >= 0 && p.wall_allow <= 5)) {
    return bad("wall_allow", p.wall_allow, "in [0, 5] metres");
  }
  if (!(p.wall_softness > 0 && p.wall_softness <= 5)) {
    return bad("wall_softness", p.wall_softness, "in (0, 5] metres");
  }
  if (!(p.keep_distance > 0)) {
    return bad("keep_distance", p.keep_distance, "> 0 (floors fade out within it of portals)");
  }
  if (!(p.floor_amplitude >= 0 && p.floor_amplitude <= 2)) {
    return bad("floor_amplitude", p.floor_amplitude, "in [0, 2] metres");
  }
  if (!noise_frequency(p.floor_frequency)) {
    return bad("floor_frequency", p.floor_frequency, kFrequencyRule);
  }
  if (!noise_frequency(p.roughness_frequency)) {
    return bad("roughness_frequency", p.roughness_frequency, kFrequencyRule);
  }
  if (!noise_frequency(p.mineral_frequency)) {
    return bad("mineral_frequency", p.mineral_frequency, kFrequencyRule);
  }
  return {};
}

core::GrottoShape shape_for(const MeshParams& p, Lod lod) {
  const LodParams& l = p.lods[static_cast<int>(lod)];
  core::GrottoShape s{};
  s.octaves = static_cast<core::uint>(l.octaves);
  for (int k = 0; k < GROTTO_MAX_OCTAVES; ++k) {
    s.frequency[k] = static_cast<float>(p.octave_frequency[k]);
    s.amplitude[k] = static_cast<float>(p.octave_amplitude[k]);
  }
  s.rim_frequency = static_cast<float>(p.rim_frequency);
  s.rim_amplitude = static_cast<float>(p.rim_amplitude);
  s.fade_distance = static_cast<float>(p.fade_distance);
  s.rim_min_radius = static_cast<float>(p.rim_min_radius);
  s.rim_softness = static_cast<float>(p.rim_softness);
  s.big_frequency = static_cast<float>(p.big_frequency);
  s.big_fade_distance = static_cast<float>(p.big_fade_distance);
  s.roundness = static_cast<float>(p.roundness);
  s.passage_roundness = static_cast<float>(p.passage_roundness);
  s.tension = static_cast<float>(p.tension);
  s.axis_fade = static_cast<float>(p.axis_fade_edges * l.edge_length);
  s.keep_distance = static_cast<float>(p.keep_distance);
  s.wall_allow = static_cast<float>(p.wall_allow);
  s.wall_softness = static_cast<float>(p.wall_softness);
  s.floor_amplitude = static_cast<float>(p.floor_amplitude);
  s.floor_frequency = static_cast<float>(p.floor_frequency);
  // The cut keeps half an edge clear of each portal plane for the stitch strip.
  s.remove_band = static_cast<float>(0.5 * l.edge_length);
  return s;
}

}  // namespace grotto::mesh
