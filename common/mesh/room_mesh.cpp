#include "common/mesh/room_mesh.hpp"

#include <algorithm>
#include <cassert>
#include <chrono>
#include <cmath>
#include <map>
#include <numeric>

#include "common/cave/geology.hpp"
#include "common/core/detmath.hpp"
#include "common/core/grid.hpp"
#include "common/mesh/deform_lanes.hpp"

namespace grotto::mesh {
namespace {

using core::float3;

constexpr int kMaxCutRounds = 16;

Vec3 to_vec(float3 f) {
  return {f.x, f.y, f.z};
}
float3 to_f3(Vec3 v) {
  return {static_cast<float>(v.x), static_cast<float>(v.y), static_cast<float>(v.z)};
}
// Distance from v to a portal's opening: its plane within its passage's section (the disc drawn
// out to the section's shape), its rim beyond.
double disc_distance(const core::GrottoPortal& p, Vec3 v) {
  Vec3 rel = v - Vec3{p.cx, p.cy, p.cz};
  Vec3 n{p.nx, p.ny, p.nz};
  double h = dot(rel, n);
  Vec3 in_plane = rel - n * h;
  double along = length(in_plane);
  double extent = p.radius;
  if (along > 1e-9)
    extent *= static_cast<double>(core::grotto_section(&p, to_f3(in_plane / along)));
  double radial = std::max(0.0, along - extent);
  return std::sqrt(h * h + radial * radial);
}

// Height of a room-frame point above a portal plane, on the room's side positive.
double height(const core::GrottoPortal& p, Vec3 v) {
  return -((v.x - p.cx) * p.nx + (v.y - p.cy) * p.ny + (v.z - p.cz) * p.nz);
}

// The band before a portal is cut for the stitch, but a patch of band far from every portal's
// hole (where a big room's wall runs close to a plane's extension beside a small portal) is not
// in the way of any stitch: its vertices stay when none of them crossed a plane. Removed
// vertices are kept unless they are connected, through removed vertices, to a cap_vertex.
void keep_stray_band(const DonorSphere& donor, std::span<const float> clearance,
                     const std::vector<uint32_t>& cap_vertex, std::vector<char>& removed) {
  const size_t nv = removed.size();
  const auto& start = donor.adjacent_start;
  std::vector<char> reached(nv, 0);
  std::vector<uint32_t> queue;
  for (uint32_t c : cap_vertex) {
    if (c != UINT32_MAX && !reached[c]) reached[c] = 1, queue.push_back(c);
  }
  for (size_t q = 0; q < queue.size(); ++q) {
    for (uint32_t e = start[queue[q]]; e < start[queue[q] + 1]; ++e) {
      uint32_t w = donor.adjacent[e];
      if (removed[w] && !reached[w]) reached[w] = 1, queue.push_back(w);
    }
  }
  for (size_t v = 0; v < nv; ++v) {
    if (removed[v] && !reached[v] && clearance[v] >= 0) removed[v] = 0;
  }
}

// Labels of donor triangles: kept, or the portal whose hole a triangle is in, or one of these.
constexpr uint8_t kKeptLabel = 255;
constexpr uint8_t kOtherLabel = 254;  // a hole of no portal, or of several at once
constexpr uint8_t kCutLabel = 253;    // not kept, its hole not known yet
static_assert(GROTTO_MAX_PORTALS < kCutLabel);

// The kept part of the donor: triangles with no removed vertex, restricted to the largest
// edge-connected piece. Returns one label per donor triangle: kKeptLabel or kCutLabel.
std::vector<uint8_t> kept_triangles(const DonorSphere& donor, const std::vector<char>& removed,
                                    AssembleStats& stats) {
  const auto& in = donor.indices;
  const size_t nt = in.size() / 3;
  // piece[t]: kRemoved, kUnseen (kept, not reached yet), or the piece's number. One array and
  // one test per neighbour, no branches on the removed flags: the fill is a tenth of assembling.
  constexpr uint32_t kRemoved = UINT32_MAX - 1, kUnseen = UINT32_MAX;
  std::vector<uint32_t> piece(nt);
  for (size_t t = 0; t < nt; ++t) {
    bool gone = (removed[in[3 * t]] | removed[in[3 * t + 1]] | removed[in[3 * t + 2]]) != 0;
    piece[t] = gone ? kRemoved : kUnseen;
  }
  // Flood fill over shared edges; keep the largest piece (the first of the largest).
  std::vector<uint32_t> stack(nt);
  std::vector<size_t> sizes;
  for (size_t seed = 0; seed < nt; ++seed) {
    if (piece[seed] != kUnseen) continue;
    uint32_t id = static_cast<uint32_t>(sizes.size());
    size_t size = 0, top = 0;
    stack[top++] = static_cast<uint32_t>(seed);
    piece[seed] = id;
    while (top > 0) {
      uint32_t t = stack[--top];
      ++size;
      for (int k = 0; k < 3; ++k) {
        uint32_t n = donor.neighbours[3 * t + k];
        if (piece[n] == kUnseen) {
          piece[n] = id;
          stack[top++] = n;
        }
      }
    }
    sizes.push_back(size);
  }
  std::vector<uint8_t> kept(nt, kCutLabel);
  if (sizes.empty()) return kept;
  uint32_t best =
      static_cast<uint32_t>(std::max_element(sizes.begin(), sizes.end()) - sizes.begin());
  for (size_t t = 0; t < nt; ++t) {
    kept[t] = piece[t] == best ? kKeptLabel : kCutLabel;
    stats.fragments_dropped += piece[t] != best && piece[t] != kRemoved;
  }
  return kept;
}

// Labels the holes of a cut (kept_triangles' labels; thesis §3.1.7: one hole per portal). A
// portal's hole grows from its cap (the donor vertices that started beyond the portal; a vertex
// of each in cap_vertex, or UINT32_MAX) across edges with a removed end, then takes in the rest
// of the cut next to it (triangles joined to it only by edges between kept vertices: a band
// vertex's fan, a dropped fragment). Where two portals lie close, their holes can meet across
// such an edge, with kept vertices between them but no triangle (seed 42,
// 33666.-46459.64248.r89); they stay two holes and the edge is in both loops. Holes joined
// through a removed vertex, which no loop can pass, are one hole of several portals
// (kOtherLabel, as are holes of no portal's cap). Returns whether two holes meet at an edge.
bool label_holes(const DonorSphere& donor, const std::vector<char>& removed,
                 const std::vector<uint32_t>& cap_vertex, std::vector<uint8_t>& label) {
  const auto& in = donor.indices;
  const size_t np = cap_vertex.size();
  std::vector<char> shared(np, 0);  // the portal's hole meets another's through a removed vertex
  bool any_shared = false, fronts = false;
  std::vector<uint32_t> queue;
  for (size_t i = 0; i < np; ++i) {
    if (cap_vertex[i] == UINT32_MAX) continue;
    uint32_t t = donor.corner[cap_vertex[i]] / 3;  // not kept: it has a removed vertex
    if (label[t] == kCutLabel) {
      label[t] = static_cast<uint8_t>(i);
      queue.push_back(t);
    } else {
      shared[label[t]] = shared[i] = any_shared = true;
    }
  }
  // First across edges with a removed end only, then (where any triangle is left) across any.
  const auto cut =
      static_cast<size_t>(label.size() - std::count(label.begin(), label.end(), kKeptLabel));
  for (bool any_edge : {false, true}) {
    if (any_edge && queue.size() == cut) break;
    for (size_t head = 0; head < queue.size(); ++head) {
      uint32_t t = queue[head];
      for (int k = 0; k < 3; ++k) {
        uint32_t n = donor.neighbours[3 * t + k];
        if (label[n] == kKeptLabel || label[n] == label[t]) continue;
        bool removed_end = removed[in[3 * t + k]] || removed[in[3 * t + (k + 1) % 3]];
        if (label[n] == kCutLabel) {
          if (!removed_end && !any_edge) continue;
          label[n] = label[t];
          queue.push_back(n);
        } else if (removed_end) {
          shared[label[n]] = shared[label[t]] = any_shared = true;
        } else {
          fronts = true;
        }
      }
    }
  }
  if (any_shared || queue.size() < cut) {
    for (uint8_t& l : label) {
      if (l == kCutLabel || (l < np && shared[l])) l = kOtherLabel;
    }
  }
  return fronts;
}

// The boundary edge that leaves vertex `a` along the boundary of the hole across donor corner
// `e` (triangle e / 3, outside the hole, edge a -> b in the donor's order, flipped b -> a): turn
// about `a` through the hole's triangles until one outside it. Returns that triangle's corner.
// Where a's fan meets one hole once this is the only edge leaving `a`; where holes meet at `a`
// (a pinch, or an edge between two holes) it keeps each loop on its own hole.
uint32_t next_boundary_edge(const DonorSphere& donor, const std::vector<uint8_t>& label,
                            uint32_t e) {
  const auto& in = donor.indices;
  const uint32_t a = in[e];
  auto corner_of = [&](uint32_t t) { return in[3 * t] == a ? 0u : (in[3 * t + 1] == a ? 1u : 2u); };
  const uint8_t hole = label[donor.neighbours[e]];
  for (uint32_t r = donor.neighbours[e];;) {
    uint32_t t = donor.neighbours[3 * r + corner_of(r)];          // across r's edge leaving a
    if (label[t] != hole) return 3 * t + (corner_of(t) + 2) % 3;  // t's edge arriving at a
    r = t;
  }
}

// Boundary loops of the holes, each following the direction of the inside-facing (flipped)
// triangles, as donor vertex indices, with the label of each loop's hole. A vertex where holes
// meet is in each of their loops (twice in one loop where a hole touches itself); `pinches`
// lists those vertices.
void boundary_loops(const DonorSphere& donor, const std::vector<uint8_t>& label, bool fronts,
                    std::vector<std::vector<uint32_t>>& loops, std::vector<uint8_t>& loop_labels,
                    std::vector<uint32_t>& pinches) {
  const auto& in = donor.indices;
  // out[b]: the donor corner of the one boundary edge leaving b; kPinch where several leave.
  constexpr uint32_t kNone = UINT32_MAX, kPinch = UINT32_MAX - 1;
  std::vector<uint32_t> out(donor.directions.size(), kNone);
  std::vector<uint32_t> starts;
  auto add = [&](size_t t, int k) {
    // Donor edge a->b is b->a in the flipped triangle.
    const auto e = static_cast<uint32_t>(3 * t + k);
    uint32_t b = in[3 * t + (k + 1) % 3];
    if (out[b] == kNone) {
      out[b] = e;
    } else if (out[b] != kPinch) {
      out[b] = kPinch;
      pinches.push_back(b);
    }
    starts.push_back(e);
  };
  for (size_t t = 0; t < label.size(); ++t) {
    if (label[t] != kKeptLabel) continue;
    for (int k = 0; k < 3; ++k) {
      if (label[donor.neighbours[3 * t + k]] != kKeptLabel) add(t, k);
    }
  }
  for (size_t t = 0; fronts && t < label.size(); ++t) {  // edges between two holes
    if (label[t] == kKeptLabel) continue;
    for (int k = 0; k < 3; ++k) {
      uint8_t hole = label[donor.neighbours[3 * t + k]];
      if (hole != kKeptLabel && hole != label[t]) add(t, k);
    }
  }
  std::vector<char> used(in.size(), 0);
  for (uint32_t start : starts) {
    if (used[start]) continue;
    std::vector<uint32_t> loop;
    for (uint32_t e = start; !used[e];) {
      used[e] = 1;
      uint32_t from = in[e - e % 3 + (e % 3 + 1) % 3];
      loop.push_back(from);
      uint32_t to = in[e];
      assert(out[to] != kNone);  // a closed donor: a boundary edge into `to` has one out of it
      e = out[to] == kPinch ? next_boundary_edge(donor, label, e) : out[to];
    }
    loops.push_back(std::move(loop));
    loop_labels.push_back(label[donor.neighbours[start]]);
  }
}

// The pinches to cut away: all but those where the holes of different portals meet. Thesis
// §3.1.7 makes one hole per portal; where two portals lie close together the wall between their
// holes can narrow to one vertex, and cutting that vertex away merged the two holes into one,
// leaving a portal without a hole (seed 7, 676.1.-2.r5). Such a vertex stays, in both loops, and
// each stitch closes its side of the vertex's fan (so do the ends of an edge between two holes,
// label_holes). A hole touching itself, or a hole that is no single portal's, is cut as before.
std::vector<uint32_t> pinches_to_cut(const std::vector<std::vector<uint32_t>>& loops,
                                     const std::vector<uint8_t>& loop_labels,
                                     const std::vector<uint32_t>& pinches, size_t np) {
  std::vector<uint32_t> cut;
  for (uint32_t v : pinches) {
    std::vector<uint8_t> seen;  // the labels of v's loops, one entry per visit
    for (size_t l = 0; l < loops.size(); ++l) {
      for (uint32_t u : loops[l]) {
        if (u == v) seen.push_back(loop_labels[l]);
      }
    }
    std::sort(seen.begin(), seen.end());
    bool portals_apart =
        seen.back() < np && std::adjacent_find(seen.begin(), seen.end()) == seen.end();
    if (!portals_apart) cut.push_back(v);
  }
  return cut;
}

// A hall's beds from the world's geology (deform_core.h's grotto_beds): the breaks between
// packages at least kMinPackage thick from its floor to above its ceiling's top, each package's
// notch from its hardness (the softest stand back kNotch x the radius, at most kMaxNotch).
void set_beds(const MeshContext& ctx, const cave::Room& room, core::GrottoRoom& record) {
  constexpr double kMinPackage = 1.5, kNotch = 0.06, kMaxNotch = 1.5;
  const double r = room.sphere.radius;
  const cave::Geology g = cave::geology_at(ctx.world(), room.sphere.centre);
  const std::vector<cave::BedBreak> breaks = cave::bed_breaks(
      ctx.world(), room.sphere.centre, 0.6 * r, 0.7 * r, kMinPackage, GROTTO_MAX_BEDS);
  record.bed_nx = static_cast<float>(g.bedding_normal.x);
  record.bed_ny = static_cast<float>(g.bedding_normal.y);
  record.bed_nz = static_cast<float>(g.bedding_normal.z);
  record.bed_count = static_cast<core::uint>(breaks.size());
  record.bed_step = 1.0f;
  const double notch = std::min(kMaxNotch, kNotch * r);
  for (size_t i = 0; i < breaks.size(); ++i) {
    const double soft = 1 - breaks[i].hardness;
    record.bed_at[i] = static_cast<float>(breaks[i].offset);
    record.bed_notch[i] = static_cast<float>(notch * soft * soft);
  }
}

// How a passage (two portals) grows between its ends (deform_core.h's grotto_grow): as the section
// the geology gives its middle would (a canyon cut deeper, a lens spread along its bed and
// lowered, as far as its lower end leaves the clear height), and held:
//   - within 0.9 of the room's sphere, as far as its wider end's reach allows;
//   - less across where it bends (its widened wall would reach across a portal's plane, which runs
//     on beyond the disc into the room);
//   - not along its height where a portal plane lies nearly level (a shaft's: the wall would
//     cross it).
void set_growth(const MeshContext& ctx, const cave::Room& room, core::GrottoRoom& record) {
  const cave::Portal& a = room.portals[0];
  const cave::Portal& b = room.portals[1];
  const cave::PassageSection end_a =
      cave::passage_section(ctx.world(), a.centre, a.normal, a.radius);
  const cave::PassageSection end_b =
      cave::passage_section(ctx.world(), b.centre, b.normal, b.radius);
  const cave::PassageSection middle =
      cave::passage_section(ctx.world(), (a.centre + b.centre) * 0.5,
                            normalize(b.centre - a.centre), 0.5 * (a.radius + b.radius));
  // An end's farthest extent: its ellipse's, or with a slot its reach (the smooth maximum that
  // joins the slot to the ellipse bulges below).
  const auto extent_of = [](const cave::Portal& p, const cave::PassageSection& s) {
    return p.radius *
           (s.slot_depth > 0 ? cave::section_reach(s) : std::max(s.half_width, s.half_height));
  };
  const double extent = std::max(extent_of(a, end_a), extent_of(b, end_b));
  const double room_for = std::max(0.0, 0.9 * room.sphere.radius / extent - 1);
  const auto smooth = [](double x) {
    x = std::clamp(x, 0.0, 1.0);
    return x * x * (3 - 2 * x);
  };
  const double straight = smooth((0.1 - dot(a.normal, b.normal)) / 0.6);
  const double upright =
      smooth((0.85 - std::max(std::abs(a.normal.y), std::abs(b.normal.y))) / 0.3);
  const double lowest = std::min(cave::section_clear_height(end_a, a.radius),
                                 cave::section_clear_height(end_b, b.radius));
  const double deepen =
      middle.deepen >= 0
          ? middle.deepen
          : std::max(middle.deepen, -std::max(0.0, 1 - cave::kMinClearHeight / lowest));
  record.grow_widen = static_cast<float>(std::min(middle.widen, room_for) * straight);
  record.grow_deepen = static_cast<float>(std::min(deepen, room_for) * upright);
}

}  // namespace

DeformInput prepare_room(const MeshContext& ctx, const cave::Room& room, Lod lod) {
  DeformInput in;
  in.room = room;
  in.lod = lod;
  in.origin = grid::snap(room.sphere.centre);
  in.donor = donor_sphere(std::min(donor_frequency(room.sphere.radius, ctx.edge_length(lod)),
                                   ctx.params().lods[static_cast<int>(lod)].max_frequency));
  Vec3 o = room.sphere.centre - in.origin;
  core::float3 w = ctx.noise_position(in.origin);
  const MeshParams& p = ctx.params();
  bool big = room.sphere.radius >= p.big_room_radius;
  in.record = {};
  in.record.ox = static_cast<float>(o.x);
  in.record.oy = static_cast<float>(o.y);
  in.record.oz = static_cast<float>(o.z);
  in.record.radius = static_cast<float>(room.sphere.radius);
  in.record.wx = w.x;
  in.record.wy = w.y;
  in.record.wz = w.z;
  in.record.big_amplitude = big ? static_cast<float>(p.big_amplitude * room.sphere.radius) : 0.0f;
  if (std::optional<double> floor = cave::floor_height(ctx.world().params(), room.sphere)) {
    in.record.has_floor = 1;
    in.record.floor_y = static_cast<float>(*floor - in.origin.y);
  }
  if (std::optional<cave::Ceiling> ceiling =
          cave::room_ceiling(ctx.world().params(), room.sphere)) {
    in.record.ceiling_y = static_cast<float>(ceiling->spring - in.origin.y);
    in.record.ceiling_bend = static_cast<float>(ceiling->bend);
    in.record.ceiling_squash = static_cast<float>(ceiling->squash);
  }
  if (big) set_beds(ctx, room, in.record);
  if (room.portals.size() == 2) set_growth(ctx, room, in.record);
  in.record.first_portal = 0;
  in.record.portal_count = static_cast<core::uint>(room.portals.size());
  in.record.first_vertex = 0;
  in.record.vertex_count = static_cast<core::uint>(in.donor->directions.size());
  in.record.lod = static_cast<core::uint>(lod);
  in.record.noise_seed = ctx.noise_seed();
  in.channel_frequencies = {static_cast<float>(p.roughness_frequency),
                            static_cast<float>(3 * p.roughness_frequency),
                            static_cast<float>(p.mineral_frequency)};
  for (const cave::Portal& portal : room.portals) {
    in.portals.push_back(portal_record(ctx, room, portal, in.origin));
  }
  return in;
}

GROTTO_LANES_CLONES void deform_cpu(const MeshContext& ctx, const DeformInput& input,
                                    std::span<float3> positions, std::span<float> clearance) {
  assert(input.record.noise_seed == ctx.noise_seed());  // prepared for this world
  // Four vertices per call in SIMD lanes (deform_lanes.hpp), each lane bit-identical to
  // core::grotto_deform_vertex; the last group repeats its last vertex in the unused lanes.
  namespace lanes = core::lanes;
  const auto& dirs = input.donor->directions;
  const size_t n = dirs.size();
  const auto shape = lanes::table<lanes::GrottoShape>(ctx.shape(input.lod));
  const auto record = lanes::table<lanes::GrottoRoom>(input.record);
  lanes::GrottoPortal portals[GROTTO_MAX_PORTALS];
  assert(input.portals.size() <= GROTTO_MAX_PORTALS);
  for (size_t i = 0; i < input.portals.size(); ++i)
    portals[i] = lanes::table<lanes::GrottoPortal>(input.portals[i]);
  for (size_t i = 0; i < n; i += lanes::kLanes) {
    float x[lanes::kLanes], y[lanes::kLanes], z[lanes::kLanes];
    for (int k = 0; k < lanes::kLanes; ++k) {
      const float3& d = dirs[std::min(i + k, n - 1)];
      x[k] = d.x;
      y[k] = d.y;
      z[k] = d.z;
    }
    lanes::gfloat3 dir = {lanes::load(x), lanes::load(y), lanes::load(z)};
    lanes::gfloat least;
    lanes::gfloat3 p =
        lanes::grotto_deform_vertex(record.noise_seed, &shape, &record, portals, dir, &least);
    for (int k = 0; k < lanes::kLanes && i + k < n; ++k) {
      positions[i + k] = {p.x[k], p.y[k], p.z[k]};
      clearance[i + k] = least[k];
    }
  }
}

void deform_reference(const MeshContext& ctx, const DeformInput& input, std::span<float3> positions,
                      std::span<float> clearance) {
  assert(input.record.noise_seed == ctx.noise_seed());
  const auto& dirs = input.donor->directions;
  for (size_t i = 0; i < dirs.size(); ++i) {
    positions[i] =
        core::grotto_deform_vertex(input.record.noise_seed, &ctx.shape(input.lod), &input.record,
                                   input.portals.data(), dirs[i], &clearance[i]);
  }
}

GROTTO_LANES_CLONES void detail_channels(const MeshContext& ctx, Vec3 origin,
                                         std::span<const float3> positions,
                                         std::span<float> roughness, std::span<float> mineral) {
  namespace lanes = core::lanes;
  const MeshParams& p = ctx.params();
  const uint32_t seed = ctx.noise_seed();
  const auto f_rough = static_cast<float>(p.roughness_frequency);
  const auto f_rough3 = static_cast<float>(3 * p.roughness_frequency);
  const auto f_mineral = static_cast<float>(p.mineral_frequency);
  const size_t n = positions.size();
  for (size_t i = 0; i < n; i += lanes::kLanes) {
    float x[lanes::kLanes], y[lanes::kLanes], z[lanes::kLanes];
    for (int k = 0; k < lanes::kLanes; ++k) {
      const float3& q = positions[std::min(i + k, n - 1)];
      float3 wk = ctx.noise_position(origin + Vec3{q.x, q.y, q.z});
      x[k] = wk.x;
      y[k] = wk.y;
      z[k] = wk.z;
    }
    lanes::gfloat3 w = {lanes::load(x), lanes::load(y), lanes::load(z)};
    lanes::gfloat r = lanes::grotto_noise3(seed, w, f_rough);
    lanes::gfloat r2 = lanes::grotto_noise3(seed, w, f_rough3);
    lanes::gfloat rough = lanes::grotto_clamp01(0.5f + 0.7f * r + 0.3f * r2);
    lanes::gfloat m = lanes::grotto_noise3(seed, w, f_mineral);
    lanes::gfloat min = lanes::grotto_smooth((m - 0.2f) * 4.0f);
    for (int k = 0; k < lanes::kLanes && i + k < n; ++k) {
      roughness[i + k] = rough[k];
      mineral[i + k] = min[k];
    }
  }
}

void detail_channels_reference(const MeshContext& ctx, Vec3 origin,
                               std::span<const float3> positions, std::span<float> roughness,
                               std::span<float> mineral) {
  const MeshParams& p = ctx.params();
  for (size_t v = 0; v < positions.size(); ++v) {
    float3 w = ctx.noise_position(origin + Vec3{positions[v].x, positions[v].y, positions[v].z});
    float r = core::grotto_noise3(ctx.noise_seed(), w, static_cast<float>(p.roughness_frequency));
    float r2 =
        core::grotto_noise3(ctx.noise_seed(), w, static_cast<float>(3 * p.roughness_frequency));
    roughness[v] = core::grotto_clamp01(0.5f + 0.7f * r + 0.3f * r2);
    float m = core::grotto_noise3(ctx.noise_seed(), w, static_cast<float>(p.mineral_frequency));
    mineral[v] = core::grotto_smooth((m - 0.2f) * 4.0f);
  }
}

void fill_detail_channels(const MeshContext& ctx, RoomMesh& mesh) {
  mesh.roughness.resize(mesh.positions.size());
  mesh.mineral.resize(mesh.positions.size());
  detail_channels(ctx, mesh.origin, mesh.positions, mesh.roughness, mesh.mineral);
}

Result<RoomMesh> assemble_room(const MeshContext& ctx, const DeformInput& input,
                               std::span<const float3> positions, std::span<const float> clearance,
                               AssembleStats* stats_out, ChannelsBy channels,
                               DonorChannels donor_channels) {
  AssembleStats stats;
  using clock = std::chrono::steady_clock;
  auto lap = [last = clock::now()](double& into) mutable {
    auto now = clock::now();
    into += std::chrono::duration<double>(now - last).count();
    last = now;
  };
  const DonorSphere& donor = *input.donor;
  const size_t nv = donor.directions.size();
  const size_t np = input.portals.size();
  const double band = ctx.shape(input.lod).remove_band;
  const bool from_donor = !donor_channels.roughness.empty();
  assert(!from_donor ||
         (channels == ChannelsBy::kAssemble && donor_channels.roughness.size() == nv &&
          donor_channels.mineral.size() == nv));
  auto name = [&] { return input.room.id.to_string(); };  // for errors only

  // Thesis §3.1.7: vertices on the wrong side of a portal go, and so does a band before it to
  // leave room for the stitch; so does every donor vertex that started beyond a portal, so each
  // portal gets a hole even where the deformation pulled vertices back.
  // cap_vertex[i]: a donor vertex that started beyond portal i, where its hole grows from.
  std::vector<char> removed(nv, 0);
  std::vector<uint32_t> cap_vertex(np, UINT32_MAX);
  size_t caps_found = 0;
  Vec3 o{input.record.ox, input.record.oy, input.record.oz};
  for (size_t v = 0; v < nv; ++v) {
    removed[v] = clearance[v] < band;
    if (removed[v] && caps_found == np) continue;
    Vec3 donor_point = o + to_vec(donor.directions[v]) * input.record.radius;
    for (size_t i = 0; i < np; ++i) {
      if (height(input.portals[i], donor_point) < 0) {
        removed[v] = 1;
        if (cap_vertex[i] == UINT32_MAX) cap_vertex[i] = static_cast<uint32_t>(v), ++caps_found;
      }
    }
  }

  keep_stray_band(donor, clearance, cap_vertex, removed);

  std::vector<uint8_t> label;  // per donor triangle: kept, or the hole it is in
  std::vector<std::vector<uint32_t>> loops;
  for (int round = 0;; ++round) {
    label = kept_triangles(donor, removed, stats);
    bool fronts = label_holes(donor, removed, cap_vertex, label);
    loops.clear();
    std::vector<uint8_t> loop_labels;
    std::vector<uint32_t> pinches;
    boundary_loops(donor, label, fronts, loops, loop_labels, pinches);
    std::vector<uint32_t> cut = pinches_to_cut(loops, loop_labels, pinches, np);
    stats.pinches_kept = static_cast<int>(pinches.size() - cut.size());
    if (cut.empty()) break;
    if (round == kMaxCutRounds) {
      return Error{ErrorCode::kInternal, "room " + name() + ": holes still touch after " +
                                             std::to_string(kMaxCutRounds) + " cuts"};
    }
    for (uint32_t v : cut)
      removed[v] = 1;
    stats.pinches_removed += static_cast<int>(cut.size());
  }

  // The kept triangles, flipped to face the inside (the donor faces outwards); room for the
  // stitches (one triangle per hole and rim vertex).
  size_t boundary = 0;
  for (const auto& loop : loops)
    boundary += loop.size();
  const auto kept_count = static_cast<size_t>(std::count(label.begin(), label.end(), kKeptLabel));
  std::vector<uint32_t> tris(3 * kept_count);
  tris.reserve(3 * (kept_count + 2 * boundary));
  for (size_t t = 0, j = 0; t < label.size(); ++t) {
    if (label[t] == kKeptLabel) {
      tris[j++] = donor.indices[3 * t];
      tris[j++] = donor.indices[3 * t + 2];
      tris[j++] = donor.indices[3 * t + 1];
    }
  }

  // Each boundary loop belongs to the portal whose disc its vertices are nearest (not the plane:
  // a big room's wall next to one portal may lie closer to a neighbouring portal's plane, which
  // the sphere meets at a shallow angle, than to its own).
  std::vector<int> loop_of_portal(np, -1);
  for (size_t l = 0; l < loops.size(); ++l) {
    std::vector<int> votes(np, 0);
    for (uint32_t v : loops[l]) {
      size_t best = 0;
      double best_d = 1e300;
      for (size_t i = 0; i < np; ++i) {
        double d = disc_distance(input.portals[i], to_vec(positions[v]));
        if (d < best_d) best = i, best_d = d;
      }
      ++votes[best];
    }
    size_t portal = std::max_element(votes.begin(), votes.end()) - votes.begin();
    if (np == 0 || loop_of_portal[portal] >= 0) {
      return Error{ErrorCode::kInternal, "room " + name() + ": " + std::to_string(loops.size()) +
                                             " holes for " + std::to_string(np) + " portals"};
    }
    loop_of_portal[portal] = static_cast<int>(l);
  }

  lap(stats.cut_seconds);

  // Stitch every hole to its portal's canonical rim (thesis §3.1.7: the polar-angle weld, made
  // against the shared loop instead of the neighbour's mesh).
  std::vector<float3> pos(positions.begin(), positions.end());
  std::vector<float3> rim_normals;
  std::vector<int8_t> rim_portal(nv, -1);
  std::vector<uint16_t> rim_index(nv, 0);
  for (size_t i = 0; i < np; ++i) {
    if (loop_of_portal[i] < 0) {
      return Error{ErrorCode::kInternal, "room " + name() + ": no hole at portal to " +
                                             input.room.portals[i].neighbour.to_string()};
    }
    const std::vector<uint32_t>& b = loops[loop_of_portal[i]];
    RimLoop rim = canonical_rim(ctx, input.room, input.room.portals[i], input.lod);
    const uint32_t base = static_cast<uint32_t>(pos.size());
    const int k_count = static_cast<int>(rim.positions.size());
    for (int k = 0; k < k_count; ++k) {
      pos.push_back(to_f3(rim.positions[k] - input.origin));  // exact: both on the grid
      rim_portal.push_back(static_cast<int8_t>(i));
      rim_index.push_back(static_cast<uint16_t>(k));
    }
    rim_normals.insert(rim_normals.end(), rim.normals.begin(), rim.normals.end());

    // Orientation of the hole about the canonical normal (shoelace in the portal plane).
    Vec3 c = rim.centre - input.origin;
    auto plane = [&](uint32_t v) {
      Vec3 d = to_vec(pos[v]) - c;
      return std::pair<double, double>{dot(d, rim.e1), dot(d, rim.e2)};
    };
    double area = 0;
    for (size_t k = 0; k < b.size(); ++k) {
      auto [x0, y0] = plane(b[k]);
      auto [x1, y1] = plane(b[(k + 1) % b.size()]);
      area += x0 * y1 - x1 * y0;
    }
    const bool ccw = area > 0;
    // The rim in the hole's sense, starting at the rim vertex nearest the hole's first vertex.
    int start = 0;
    double best = 1e300;
    for (int k = 0; k < k_count; ++k) {
      double d = length_squared(to_vec(pos[base + k]) - to_vec(pos[b[0]]));
      if (d < best) best = d, start = k;
    }
    auto rim_at = [&](size_t j) {
      int k = ccw ? (start + static_cast<int>(j)) % k_count
                  : ((start - static_cast<int>(j)) % k_count + k_count) % k_count;
      return base + static_cast<uint32_t>(k);
    };
    auto dist = [&](uint32_t a, uint32_t bb) {
      return length_squared(to_vec(pos[a]) - to_vec(pos[bb]));
    };
    size_t m = b.size(), ib = 0, ic = 0;
    while (ib < m || ic < static_cast<size_t>(k_count)) {
      uint32_t b_cur = b[ib % m], b_next = b[(ib + 1) % m];
      uint32_t c_cur = rim_at(ic), c_next = rim_at(ic + 1);
      bool advance_hole = ic == static_cast<size_t>(k_count) ||
                          (ib < m && dist(b_next, c_cur) <= dist(b_cur, c_next));
      if (advance_hole) {
        tris.insert(tris.end(), {b_next, b_cur, c_cur});
        ++ib;
      } else {
        tris.insert(tris.end(), {b_cur, c_cur, c_next});
        ++ic;
      }
    }
    ++stats.loops_stitched;
  }

  lap(stats.stitch_seconds);

  // Compact: used donor vertices in order, then the rim loops.
  std::vector<uint32_t> remap(pos.size(), UINT32_MAX);
  RoomMesh mesh;
  mesh.id = input.room.id;
  mesh.lod = input.lod;
  mesh.origin = input.origin;
  for (uint32_t v : tris)
    remap[v] = 0;
  const auto used = static_cast<size_t>(std::count(remap.begin(), remap.end(), 0u));
  mesh.positions.reserve(used);
  mesh.rim_portal.reserve(used);
  mesh.rim_index.reserve(used);
  if (from_donor) {
    mesh.roughness.reserve(used);
    mesh.mineral.reserve(used);
  }
  for (size_t v = 0; v < pos.size(); ++v) {
    if (remap[v] == UINT32_MAX) continue;
    remap[v] = static_cast<uint32_t>(mesh.positions.size());
    mesh.positions.push_back(pos[v]);
    mesh.rim_portal.push_back(rim_portal[v]);
    mesh.rim_index.push_back(rim_index[v]);
    if (from_donor && v < nv) {
      mesh.roughness.push_back(donor_channels.roughness[v]);
      mesh.mineral.push_back(donor_channels.mineral[v]);
    }
  }
  mesh.indices.resize(tris.size());
  for (size_t i = 0; i < tris.size(); ++i)
    mesh.indices[i] = remap[tris[i]];

  // Normals (thesis §3.1.7): area-weighted face normals, summed per vertex; rim vertices take
  // the canonical rim normal, which the neighbour uses too, so shading is smooth across portals.
  std::vector<Vec3> acc(mesh.positions.size());
  for (size_t t = 0; t < mesh.indices.size(); t += 3) {
    Vec3 a = to_vec(mesh.positions[mesh.indices[t]]);
    Vec3 n = cross(to_vec(mesh.positions[mesh.indices[t + 1]]) - a,
                   to_vec(mesh.positions[mesh.indices[t + 2]]) - a);
    for (int k = 0; k < 3; ++k)
      acc[mesh.indices[t + k]] = acc[mesh.indices[t + k]] + n;
  }
  mesh.normals.resize(mesh.positions.size());
  size_t rim_seen = 0;
  for (size_t v = 0; v < pos.size(); ++v) {
    if (v >= nv) ++rim_seen;
    if (remap[v] == UINT32_MAX) continue;
    uint32_t out = remap[v];
    if (v >= nv) {
      mesh.normals[out] = rim_normals[rim_seen - 1];
    } else {
      double len = length(acc[out]);
      mesh.normals[out] = len > 0 ? to_f3(acc[out] / len) : float3{0, 1, 0};
    }
  }

  lap(stats.normals_seconds);

  // Detail channels from world-space fields, so rim vertices agree across rooms.
  if (channels == ChannelsBy::kCaller) {
    if (stats_out) *stats_out = stats;
    return mesh;
  }
  if (from_donor) {  // the kept donor vertices' came with the deformation: the rims' (the tail)
    const size_t donor_kept = mesh.roughness.size(), n = mesh.positions.size();
    mesh.roughness.resize(n);
    mesh.mineral.resize(n);
    detail_channels(ctx, mesh.origin, std::span(mesh.positions).subspan(donor_kept),
                    std::span(mesh.roughness).subspan(donor_kept),
                    std::span(mesh.mineral).subspan(donor_kept));
  } else {
    fill_detail_channels(ctx, mesh);
  }
  lap(stats.channels_seconds);
  if (stats_out) *stats_out = stats;
  return mesh;
}

Result<RoomMesh> build_room_mesh(const MeshContext& ctx, const cave::Room& room, Lod lod) {
  DeformInput input = prepare_room(ctx, room, lod);
  std::vector<float3> positions(input.donor->directions.size());
  std::vector<float> clearance(positions.size());
  deform_cpu(ctx, input, positions, clearance);
  return assemble_room(ctx, input, positions, clearance);
}

}  // namespace grotto::mesh
