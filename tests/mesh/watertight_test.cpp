// Watertight across independently built rooms: shared rims are identical,
// and the union of a 2x2x2 block of sectors is a closed, consistently oriented 2-manifold.
#include <gtest/gtest.h>

#include <map>
#include <tuple>

#include "tests/mesh/mesh_fixture.hpp"

namespace grotto::mesh {
namespace {

class Watertight : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    world_ = new cave::World(cave::World::create(2025, cave::LayoutParams{}).value());
    ctx_ = new MeshContext(MeshContext::create(*world_, MeshParams{}).value());
    block_ =
        new testing::BuiltBlock(testing::build_block(*ctx_, {0, 0, 0}, {1, 1, 1}, Lod::kPatch, 99));
  }
  static void TearDownTestSuite() {
    delete block_;
    delete ctx_;
    delete world_;
  }
  static int slot_of(const cave::Room& r, cave::RoomId neighbour) {
    for (size_t i = 0; i < r.portals.size(); ++i) {
      if (r.portals[i].neighbour == neighbour) return static_cast<int>(i);
    }
    return -1;
  }
  static cave::World* world_;
  static MeshContext* ctx_;
  static testing::BuiltBlock* block_;
};
cave::World* Watertight::world_ = nullptr;
MeshContext* Watertight::ctx_ = nullptr;
testing::BuiltBlock* Watertight::block_ = nullptr;

TEST_F(Watertight, every_room_of_the_block_was_built) {
  EXPECT_EQ(block_->meshes.size(), block_->region.rooms.size());
  for (const std::string& failure : block_->failures)
    ADD_FAILURE() << failure;
  EXPECT_GT(block_->meshes.size(), 500u);
}

void expect_same_rims(const RoomMesh& a, int slot_a, const RoomMesh& b, int slot_b,
                      const std::string& what) {
  testing::Rim ra = testing::rim_of(a, slot_a), rb = testing::rim_of(b, slot_b);
  ASSERT_FALSE(ra.positions.empty()) << what;
  ASSERT_EQ(ra.positions.size(), rb.positions.size()) << what;
  for (size_t k = 0; k < ra.positions.size(); ++k) {
    ASSERT_EQ(ra.positions[k], rb.positions[k]) << what << " rim vertex " << k;
    ASSERT_EQ(ra.normals[k].x, rb.normals[k].x) << what;
    ASSERT_EQ(ra.normals[k].y, rb.normals[k].y) << what;
    ASSERT_EQ(ra.normals[k].z, rb.normals[k].z) << what;
  }
}

TEST_F(Watertight, portal_rims_are_bit_identical_in_both_rooms) {
  int portals = 0;
  for (auto& [id, mesh] : block_->meshes) {
    const cave::Room& r = *block_->region.find(id);
    for (size_t i = 0; i < r.portals.size(); ++i) {
      auto other = block_->meshes.find(r.portals[i].neighbour);
      if (other == block_->meshes.end() || !(id < other->first)) continue;
      const cave::Room& n = *block_->region.find(other->first);
      expect_same_rims(mesh, static_cast<int>(i), other->second, slot_of(n, id),
                       id.to_string() + " / " + n.id.to_string());
      ++portals;
    }
  }
  EXPECT_GT(portals, 500);
}

TEST_F(Watertight, rims_match_whatever_else_was_built_before) {
  // A room rebuilt alone, at the other level of detail first, still matches its neighbour.
  const cave::Room& r = block_->region.rooms[block_->region.rooms.size() / 3];
  (void)build_room_mesh(*ctx_, r, Lod::kDetail);
  RoomMesh alone = build_room_mesh(*ctx_, r, Lod::kPatch).value();
  for (size_t i = 0; i < r.portals.size(); ++i) {
    auto other = block_->meshes.find(r.portals[i].neighbour);
    if (other == block_->meshes.end()) continue;
    expect_same_rims(alone, static_cast<int>(i), other->second,
                     slot_of(*block_->region.find(other->first), r.id), r.id.to_string());
  }
}

TEST_F(Watertight, block_union_is_a_closed_consistently_oriented_manifold) {
  // Rim vertices are shared by position; every other vertex belongs to its room.
  using Key = std::tuple<double, double, double, uint64_t, uint32_t>;
  std::map<Key, uint32_t> ids;
  auto id_of = [&](const RoomMesh& m, uint32_t v) {
    Vec3 p = m.world_position(v);
    Key key = m.rim_portal[v] >= 0 ? Key{p.x, p.y, p.z, 0, 0} : Key{0, 0, 0, m.id.packed() + 1, v};
    return ids.emplace(key, static_cast<uint32_t>(ids.size())).first->second;
  };
  std::map<std::pair<uint32_t, uint32_t>, int> directed;
  std::map<std::pair<uint32_t, uint32_t>, Vec3> leaving;  // rim edges out of the block -> portal
  double volume = 0;  // signed, of the union with its openings closed by fans
  const Vec3 ref{96, 96, 96};
  auto add_volume = [&](Vec3 a, Vec3 b, Vec3 d) {
    a = a - ref, b = b - ref, d = d - ref;
    volume += dot(a, Vec3{b.y * d.z - b.z * d.y, b.z * d.x - b.x * d.z, b.x * d.y - b.y * d.x}) / 6;
  };
  std::map<uint32_t, Vec3> position;
  for (auto& [rid, m] : block_->meshes) {
    const cave::Room& r = *block_->region.find(rid);
    std::vector<uint32_t> gid(m.vertex_count());
    for (uint32_t v = 0; v < m.vertex_count(); ++v) {
      gid[v] = id_of(m, v);
      position[gid[v]] = m.world_position(v);
    }
    for (size_t t = 0; t < m.indices.size(); t += 3) {
      add_volume(m.world_position(m.indices[t]), m.world_position(m.indices[t + 1]),
                 m.world_position(m.indices[t + 2]));
      for (int e = 0; e < 3; ++e) {
        uint32_t a = m.indices[t + e], b = m.indices[t + (e + 1) % 3];
        ++directed[{gid[a], gid[b]}];
        int slot = m.rim_portal[a];
        if (slot >= 0 && slot == m.rim_portal[b] &&
            !block_->meshes.count(r.portals[slot].neighbour)) {
          leaving[{gid[a], gid[b]}] = r.portals[slot].centre;
        }
      }
    }
  }
  size_t bad = 0, open_edges = 0;
  for (auto& [e, count] : directed) {
    bool twin = directed.count({e.second, e.first}) && directed.at({e.second, e.first}) == 1;
    if (count == 1 && twin) continue;
    if (count == 1 && leaving.count(e)) {
      ++open_edges;
      continue;
    }
    if (++bad <= 10)
      ADD_FAILURE() << "edge " << e.first << "->" << e.second << " used " << count
                    << " times, twin " << twin;
  }
  EXPECT_EQ(bad, 0u);
  RecordProperty("edges", static_cast<int>(directed.size()));
  RecordProperty("edges_leaving_the_block", static_cast<int>(open_edges));
  EXPECT_GT(open_edges, 0u);

  // Normals face the inside: with the openings closed by fans, the signed volume is negative.
  for (auto& [e, centre] : leaving)
    add_volume(position[e.second], position[e.first], centre);
  RecordProperty("signed_volume_m3", static_cast<int>(volume));
  EXPECT_LT(volume, -1000.0) << "triangles must face the inside of the cave";
}

}  // namespace
}  // namespace grotto::mesh
