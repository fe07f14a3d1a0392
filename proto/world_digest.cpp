#include "proto/world_digest.hpp"

#include <string_view>
#include <vector>

#include "common/cave/geology.hpp"
#include "common/cave/lights.hpp"
#include "common/core/bytes.hpp"
#include "common/core/grid.hpp"
#include "common/core/random.hpp"

namespace grotto::proto {
namespace {

class Canonical {
 public:
  void u64(uint64_t v) { le::append(bytes_, v); }
  void i64(int64_t v) { u64(static_cast<uint64_t>(v)); }
  void f64(double v) { le::append_f64(bytes_, v); }
  void vec(Vec3 v) { le::append_vec3(bytes_, v); }
  void text(std::string_view s) {
    u64(s.size());
    bytes_.insert(bytes_.end(), s.begin(), s.end());
  }
  const std::vector<uint8_t>& bytes() const { return bytes_; }

 private:
  std::vector<uint8_t> bytes_;
};

}  // namespace

uint64_t layout_params_digest(const cave::LayoutParams& p) {
  Canonical c;
  c.text("grotto.layout.v3");  // a new field or order is a new tag
  c.f64(p.sector_size);
  c.i64(p.gates_min);
  c.i64(p.gates_max);
  c.f64(p.gate_radius_min);
  c.f64(p.gate_radius_max);
  c.f64(p.link_radius_min);
  c.f64(p.link_radius_max);
  c.f64(p.min_portal_radius);
  c.f64(p.wall_clearance);
  c.f64(p.portal_gap);
  c.f64(p.floor_min_radius);
  c.f64(p.floor_depth);
  c.f64(p.ceiling_spring);
  c.f64(p.ceiling_bend);
  c.f64(p.ceiling_rise);
  c.f64(p.region_scale);
  c.i64(p.region_sharpness);
  for (const cave::Character& k : p.characters) {
    c.text(k.name);
    c.i64(k.room_count);
    c.f64(k.big_probability);
    c.f64(k.small_radius_min);
    c.f64(k.small_radius_max);
    c.f64(k.big_radius_min);
    c.f64(k.big_radius_max);
    c.vec(k.bias);
    c.f64(k.tunnel_chance);
    c.i64(k.loops);
    c.f64(k.hall_probability);
    c.f64(k.hall_radius_min);
    c.f64(k.hall_radius_max);
  }
  return fold_digest(0xcbf29ce484222325ull, c.bytes());
}

uint64_t fold_digest(uint64_t digest, std::span<const uint8_t> bytes) {
  return fnv1a64(bytes.data(), bytes.size(), digest);
}

uint64_t world_params_digest(const cave::LayoutParams& layout, const mesh::MeshParams& m) {
  Canonical c;
  for (const auto& l : m.lods) {
    c.f64(l.edge_length);
    c.f64(static_cast<double>(l.octaves));
  }
  // Version 5 of the deformation: halls keep their sphere, rest on floors and lower their wall
  // onto a ceiling that steps along the beds of the world's geology, with notches and ledges in
  // their walls; donors are capped by frequency, the spline's rim point is pulled in near a
  // portal's axis line, every rim is its passage's section from the geology, and a passage grows
  // between its ends. The algorithm itself is part of the world, not only its numbers.
  c.text("grotto.mesh.v6");
  for (const auto& l : m.lods)
    c.f64(static_cast<double>(l.max_frequency));
  for (double v : {m.axis_fade_edges, m.keep_distance, m.wall_allow, m.wall_softness,
                   m.floor_amplitude, m.floor_frequency}) {
    c.f64(v);
  }
  for (double f : m.octave_frequency)
    c.f64(f);
  for (double a : m.octave_amplitude)
    c.f64(a);
  for (double v :
       {m.rim_frequency, m.rim_amplitude, m.fade_distance, m.big_room_radius, m.big_frequency,
        m.big_amplitude, m.big_fade_distance, m.roundness, m.tension, m.roughness_frequency,
        m.mineral_frequency, m.rim_min_radius, m.rim_softness, m.passage_roundness}) {
    c.f64(v);
  }
  // The world grid moves every vertex and rim: rooms built on another grid must not share a
  // client's cache with these.
  c.f64(grid::kStep);
  // The world's lights (cave/lights.hpp) are part of the world: engines place them from the
  // same seed. Their parameters are built in (LightParams{}); the tag names the algorithm.
  const cave::LightParams lights;
  c.text(cave::kLightsVersion);
  c.i64(lights.hall_min);
  c.i64(lights.hall_max);
  for (double v : {lights.big_radius, lights.big_chance, lights.small_chance, lights.wall_fraction,
                   lights.portal_clearance, lights.floor_lift, lights.range_per_radius,
                   lights.min_range, lights.intensity_per_range2}) {
    c.f64(v);
  }
  // The world's rock (cave/geology.hpp): engines read it from the same seed.
  c.text(cave::kGeologyVersion);
  // The relief and formations the client draws and engines evaluate (common/relief/relief.hpp):
  // part of the world though no room's bytes depend on them.
  c.text(kReliefVersion);
  c.text(kFormationsVersion);
  return fold_digest(layout_params_digest(layout), c.bytes());
}

}  // namespace grotto::proto
