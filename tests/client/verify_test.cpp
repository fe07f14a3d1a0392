// client/stream's checks on received rooms, on real rooms exactly as a client holds them: built
// with the CPU reference, encoded by the room codec, decoded by decode_room. Real rooms pass
// (rims complete, seams bit-identical, gates across sectors included); one grid step, one missing
// rim vertex or one vertex out of its sphere fails.
#include <gtest/gtest.h>

#include <cmath>
#include <map>
#include <string>
#include <utility>
#include <vector>

#include "client/stream/verify.hpp"
#include "common/cave/layout.hpp"
#include "common/core/grid.hpp"
#include "common/mesh/room_mesh.hpp"
#include "tests/client/ready_room.hpp"

namespace grotto::stream {
namespace {

using cave::RoomId;

constexpr auto ready = stream::test::ready_room;

using RoomMap = std::map<RoomId, ReadyRoom>;

// Every room of a block of sectors at one level of detail.
void build(uint64_t seed, cave::SectorCoord lo, cave::SectorCoord hi, mesh::Lod lod, RoomMap& out) {
  const cave::World world = cave::World::create(seed, cave::LayoutParams{}).value();
  const mesh::MeshContext ctx = mesh::MeshContext::create(world, mesh::MeshParams{}).value();
  for (const cave::Room& r : cave::generate_region(world, lo, hi).rooms) {
    auto m = mesh::build_room_mesh(ctx, r, lod);
    ASSERT_TRUE(m.ok()) << r.id.to_string() << ": " << m.error().message;
    out.emplace(r.id, ready(m.value(), r));
  }
}

int slot_of(const ReadyRoom& r, RoomId to) {
  for (size_t i = 0; i < r.room.portals.size(); ++i)
    if (r.room.portals[i].neighbour == to) return static_cast<int>(i);
  return -1;
}

// The vertex at loop index k of portal `slot`.
size_t rim_vertex(const ReadyRoom& r, int slot, uint16_t k) {
  for (size_t v = 0; v < r.mesh.vertex_count(); ++v)
    if (r.mesh.rim_portal[v] == slot && r.mesh.rim_index[v] == k) return v;
  ADD_FAILURE() << "no rim vertex " << k << " on slot " << slot;
  return 0;
}

size_t loop_size(const ReadyRoom& r, int slot) {
  size_t n = 0;
  for (int8_t s : r.mesh.rim_portal)
    n += s == slot;
  return n;
}

void expect_bad_frame(const Status& s, const std::vector<std::string>& mentions) {
  ASSERT_FALSE(s.ok());
  EXPECT_EQ(s.error().code, ErrorCode::kBadFrame) << s.error().message;
  for (const std::string& m : mentions)
    EXPECT_NE(s.error().message.find(m), std::string::npos)
        << "'" << m << "' not in: " << s.error().message;
}

// Real rooms, built on first use (each test runs in its own process under ctest): wire lod 0
// (patch) rooms of two blocks of two sectors, whose gates on an x face (seed 42) and a y face
// (seed 7) join rooms of different sectors, and lod 1 (detail) rooms of one sector (seed 2025).
const RoomMap& patch42() {
  static const RoomMap* rooms = [] {
    auto* m = new RoomMap();
    build(42, {0, 0, 0}, {1, 0, 0}, mesh::Lod::kPatch, *m);
    return m;
  }();
  return *rooms;
}
const RoomMap& patch7() {
  static const RoomMap* rooms = [] {
    auto* m = new RoomMap();
    build(7, {0, 0, 0}, {0, 1, 0}, mesh::Lod::kPatch, *m);
    return m;
  }();
  return *rooms;
}
const RoomMap& detail2025() {
  static const RoomMap* rooms = [] {
    auto* m = new RoomMap();
    build(2025, {0, 0, 0}, {0, 0, 0}, mesh::Lod::kDetail, *m);
    return m;
  }();
  return *rooms;
}

using RoomPair = std::pair<const ReadyRoom*, const ReadyRoom*>;

// Each neighbour pair of a map once (lower id first).
std::vector<RoomPair> pairs(const RoomMap& rooms) {
  std::vector<RoomPair> out;
  for (const auto& [id, r] : rooms)
    for (const cave::Portal& p : r.room.portals) {
      auto other = rooms.find(p.neighbour);
      if (other != rooms.end() && id < p.neighbour) out.push_back({&r, &other->second});
    }
  return out;
}

// A neighbour pair of patch42() whose rooms lie in different sectors (a gate and a room of the
// upper sector).
RoomPair gate_pair() {
  for (RoomPair pr : pairs(patch42()))
    if (pr.first->room.id.sector() != pr.second->room.id.sector()) return pr;
  ADD_FAILURE() << "no pair across sectors";
  return pairs(patch42()).front();
}

class Verify : public ::testing::Test {
 protected:
  static const RoomMap& patch() { return patch42(); }
};

TEST_F(Verify, every_real_room_passes_at_both_levels_of_detail) {
  size_t rooms = 0;
  for (const RoomMap* m : {&patch42(), &patch7(), &detail2025()})
    for (const auto& [id, r] : *m) {
      Status s = verify_room(r);
      EXPECT_TRUE(s.ok()) << (s.ok() ? "" : s.error().message);
      ++rooms;
    }
  EXPECT_GT(rooms, 550u);
}

// The finding verify_room rests on, checked without it: in real rooms every portal's loop is
// complete, each index on exactly one vertex, and each edge (k, k+1 mod K) is one triangle's.
TEST_F(Verify, every_real_rim_loop_is_complete_with_each_index_once) {
  size_t loops = 0;
  for (const RoomMap* m : {&patch42(), &patch7(), &detail2025()})
    for (const auto& [id, r] : *m)
      for (size_t s = 0; s < r.room.portals.size(); ++s) {
        std::map<uint16_t, std::vector<size_t>> at;
        for (size_t v = 0; v < r.mesh.vertex_count(); ++v)
          if (r.mesh.rim_portal[v] == static_cast<int>(s)) at[r.mesh.rim_index[v]].push_back(v);
        ASSERT_GE(at.size(), 8u) << id.to_string();
        EXPECT_EQ(at.rbegin()->first, at.size() - 1) << id.to_string() << " slot " << s;
        for (const auto& [k, vs] : at)
          EXPECT_EQ(vs.size(), 1u) << id.to_string() << " slot " << s << " k " << k;
        ++loops;
      }
  EXPECT_GT(loops, 1000u);
}

TEST_F(Verify, every_real_seam_is_bit_identical_including_gates_across_sectors) {
  size_t seams = 0, across = 0;
  for (const RoomMap* m : {&patch42(), &patch7(), &detail2025()})
    for (auto [a, b] : pairs(*m)) {
      Status s = verify_seam(*a, *b);
      EXPECT_TRUE(s.ok()) << (s.ok() ? "" : s.error().message);
      Status back = verify_seam(*b, *a);
      EXPECT_TRUE(back.ok()) << (back.ok() ? "" : back.error().message);
      ++seams;
      across += a->room.id.sector() != b->room.id.sector();
    }
  EXPECT_GT(seams, 600u);
  EXPECT_GT(across, 20u);  // gates paired with rooms of both their sectors
}

TEST_F(Verify, seam_fails_when_one_rim_vertex_moves_one_grid_step) {
  auto all = pairs(patch());
  std::vector<RoomPair> some = {all[0], all[all.size() / 2], all.back(), gate_pair()};
  for (auto [a, b] : some) {
    const int slot = slot_of(*a, b->room.id);
    const uint16_t k = static_cast<uint16_t>(loop_size(*a, slot) / 2);
    for (int axis = 0; axis < 3; ++axis) {
      ReadyRoom moved = *a;
      mesh::core::float3& p = moved.mesh.positions[rim_vertex(moved, slot, k)];
      float& c = axis == 0 ? p.x : (axis == 1 ? p.y : p.z);
      c += static_cast<float>(grid::kStep);  // exact: offsets on the grid are exact floats
      expect_bad_frame(verify_seam(moved, *b),
                       {a->room.id.to_string(), b->room.id.to_string(), "k=" + std::to_string(k)});
      expect_bad_frame(verify_seam(*b, moved), {"k=" + std::to_string(k)});
    }
  }
}

TEST_F(Verify, seam_fails_when_one_rim_normal_differs) {
  auto [a, b] = gate_pair();
  const int slot = slot_of(*a, b->room.id);
  ReadyRoom changed = *a;
  mesh::core::float3& n = changed.mesh.normals[rim_vertex(changed, slot, 3)];
  n.x = std::nextafter(n.x, 2.0f);
  expect_bad_frame(verify_seam(changed, *b), {"k=3", "normal"});
}

TEST_F(Verify, seam_fails_when_one_side_lacks_a_loop_index) {
  auto [a, b] = pairs(patch())[5];
  const int slot = slot_of(*a, b->room.id);
  const uint16_t last = static_cast<uint16_t>(loop_size(*a, slot) - 1);
  for (uint16_t k : {uint16_t{0}, uint16_t{4}, last}) {
    ReadyRoom cut = *a;
    const size_t v = rim_vertex(cut, slot, k);
    cut.mesh.rim_portal[v] = -1;
    cut.mesh.rim_index[v] = 0;
    expect_bad_frame(verify_seam(cut, *b), {"loop index " + std::to_string(k)});
    expect_bad_frame(verify_seam(*b, cut), {"loop index " + std::to_string(k)});
  }
}

TEST_F(Verify, seam_fails_when_the_descriptors_disagree) {
  auto [a, b] = pairs(patch())[3];
  const int slot = slot_of(*a, b->room.id);
  ReadyRoom off = *a;
  off.room.portals[slot].centre.z = std::nextafter(off.room.portals[slot].centre.z, 1e9);
  expect_bad_frame(verify_seam(off, *b), {"centre"});
  off = *a;
  off.room.portals[slot].radius = std::nextafter(off.room.portals[slot].radius, 0.0);
  expect_bad_frame(verify_seam(off, *b), {"radi"});
  off = *a;
  off.room.portals[slot].normal = -off.room.portals[slot].normal;
  expect_bad_frame(verify_seam(off, *b), {"normal"});
}

TEST_F(Verify, seam_refuses_rooms_that_are_not_neighbours) {
  auto [a, b] = pairs(patch())[0];
  const ReadyRoom* far = nullptr;
  for (const auto& [id, r] : patch())
    if (slot_of(*a, id) < 0 && slot_of(r, a->room.id) < 0 && id != a->room.id) far = &r;
  ASSERT_NE(far, nullptr);
  Status s = verify_seam(*a, *far);
  ASSERT_FALSE(s.ok());
  EXPECT_EQ(s.error().code, ErrorCode::kInvalidArgument);
  // Listed on one side only: a broken seam, not a stranger.
  ReadyRoom one_sided = *b;
  one_sided.room.portals.erase(one_sided.room.portals.begin() + slot_of(*b, a->room.id));
  expect_bad_frame(verify_seam(*a, one_sided), {"only"});
}

TEST_F(Verify, room_fails_on_a_missing_rim_vertex_wherever_it_is_in_the_loop) {
  const ReadyRoom& r = patch().begin()->second;
  const uint16_t last = static_cast<uint16_t>(loop_size(r, 0) - 1);
  for (uint16_t k : {uint16_t{0}, uint16_t{5}, last}) {
    ReadyRoom cut = r;
    const size_t v = rim_vertex(cut, 0, k);
    cut.mesh.rim_portal[v] = -1;
    cut.mesh.rim_index[v] = 0;
    // The last index leaves 0..K-2, complete by itself: only the open loop edge shows it.
    expect_bad_frame(verify_room(cut),
                     {r.room.id.to_string(), "portal 0",
                      k == last ? "rim edge" : "loop index " + std::to_string(k)});
  }
}

TEST_F(Verify, room_fails_on_a_loop_index_on_two_vertices) {
  const ReadyRoom& r = std::next(patch().begin(), 10)->second;
  ReadyRoom twice = r;
  twice.mesh.rim_index[rim_vertex(twice, 0, 6)] = 7;
  expect_bad_frame(verify_room(twice), {"portal 0", "loop index 7 on two vertices"});
}

TEST_F(Verify, room_fails_when_a_vertex_leaves_its_sphere_beyond_the_margin) {
  const ReadyRoom& r = std::next(patch().begin(), 20)->second;
  const cave::Sphere& s = r.room.sphere;
  size_t v = 0;
  while (r.mesh.rim_portal[v] >= 0)
    ++v;
  const double limit = s.radius + vertex_sphere_margin(s.radius);
  for (double beyond : {-0.05, 0.05}) {
    ReadyRoom out = r;
    // Straight up from the centre, as a float offset from the origin (rounding: micrometres).
    const Vec3 w = s.centre + Vec3{0, limit + beyond, 0} - r.origin;
    out.mesh.positions[v] = {static_cast<float>(w.x), static_cast<float>(w.y),
                             static_cast<float>(w.z)};
    Status st = verify_room(out);
    if (beyond < 0)
      EXPECT_TRUE(st.ok()) << st.error().message;
    else
      expect_bad_frame(st, {r.room.id.to_string(), "outside its sphere"});
  }
}

TEST_F(Verify, room_fails_on_a_rim_vertex_off_its_portal_plane) {
  const ReadyRoom& r = std::next(patch().begin(), 30)->second;
  const Vec3 n = r.room.portals[0].normal;
  int axis = 0;
  for (int a = 1; a < 3; ++a)
    if (std::abs(n[a]) > std::abs(n[axis])) axis = a;
  ReadyRoom off = r;
  mesh::core::float3& p = off.mesh.positions[rim_vertex(off, 0, 2)];
  // Four steps along the normal's largest axis: at least 4/sqrt(3) steps along the normal, more
  // than the snap's sqrt(3)/2 plus the tolerance.
  const float step = static_cast<float>(4 * grid::kStep) * (n[axis] > 0 ? 1.0f : -1.0f);
  (axis == 0 ? p.x : (axis == 1 ? p.y : p.z)) += step;
  expect_bad_frame(verify_room(off), {"portal 0", "k=2", "off the portal plane"});
}

TEST_F(Verify, room_names_each_broken_vertex_attribute) {
  const ReadyRoom& r = std::next(patch().begin(), 40)->second;
  size_t v = 0;
  while (r.mesh.rim_portal[v] >= 0)
    ++v;
  struct Case {
    const char* what;
    void (*breaks)(ReadyRoom&, size_t);
    const char* mention;
  };
  const Case cases[] = {
      {"normal too long",
       [](ReadyRoom& x, size_t i) {
         mesh::core::float3& n = x.mesh.normals[i];
         n = {n.x * 1.01f, n.y * 1.01f, n.z * 1.01f};
       },
       "normal length"},
      {"roughness above 1", [](ReadyRoom& x, size_t i) { x.mesh.roughness[i] = 1.01f; }, "channel"},
      {"mineral NaN", [](ReadyRoom& x, size_t i) { x.mesh.mineral[i] = std::nanf(""); }, "channel"},
      {"rim slot past the portals",
       [](ReadyRoom& x, size_t i) {
         x.mesh.rim_portal[i] = static_cast<int8_t>(x.room.portals.size());
       },
       "rim slot"},
      {"loop index off a rim", [](ReadyRoom& x, size_t i) { x.mesh.rim_index[i] = 3; },
       "loop index but no rim"},
      {"triangle index out of range",
       [](ReadyRoom& x, size_t) {
         x.mesh.indices[1] = static_cast<uint32_t>(x.mesh.vertex_count());
       },
       "out of range"},
      {"arrays of different lengths", [](ReadyRoom& x, size_t) { x.mesh.mineral.pop_back(); },
       "different lengths"},
  };
  for (const Case& c : cases) {
    SCOPED_TRACE(c.what);
    ReadyRoom broken = r;
    c.breaks(broken, v);
    expect_bad_frame(verify_room(broken), {r.room.id.to_string(), c.mention});
  }
}

}  // namespace
}  // namespace grotto::stream
