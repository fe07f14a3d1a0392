// grotto-load --verify on real rooms (CPU reference mesh, through the room codec): neighbours
// pass, each seam is checked once, and a moved rim vertex or a portal that disagrees with its
// neighbour is counted as a failure, on the checking thread as well as directly.
#include "client/load/verifier.hpp"

#include <gtest/gtest.h>

#include <map>

#include "common/cave/layout.hpp"
#include "common/codec/room_codec.hpp"
#include "common/mesh/context.hpp"
#include "common/mesh/room_mesh.hpp"

namespace {

using grotto::cave::RoomId;
using grotto::load::PlayerVerifier;
using grotto::load::Verifier;
using grotto::load::VerifyReport;
using grotto::stream::ReadyRoom;
using RoomPtr = std::shared_ptr<const ReadyRoom>;

// The spawn room and its first neighbour, as a client holds them after their frames.
struct Pair {
  RoomPtr a, b;
};

RoomPtr ready(const grotto::mesh::MeshContext& ctx, const grotto::cave::Room& room) {
  auto m = grotto::mesh::build_room_mesh(ctx, room, grotto::mesh::Lod::kPatch);
  EXPECT_TRUE(m.ok());
  auto bytes = grotto::codec::encode_room(*m);
  EXPECT_TRUE(bytes.ok());
  grotto::codec::DecodeLimits limits;
  limits.portal_count = static_cast<int>(room.portals.size());
  auto decoded = grotto::codec::decode_room(*bytes, limits);
  EXPECT_TRUE(decoded.ok());
  auto out = std::make_shared<ReadyRoom>();
  out->room = room;
  out->origin = m->origin;
  out->mesh = std::move(decoded).value();
  out->payload_bytes = bytes->size();
  return out;
}

const Pair& rooms() {
  static const Pair pair = [] {
    auto world = *grotto::cave::World::create(7, {});
    auto ctx = *grotto::mesh::MeshContext::create(world, {});
    auto a = *grotto::cave::room(world, grotto::cave::spawn_room(world));
    auto b = *grotto::cave::room(world, a.portals.at(0).neighbour);
    return Pair{ready(ctx, a), ready(ctx, b)};
  }();
  return pair;
}

TEST(Verifier, neighbours_pass_and_each_seam_is_checked_once) {
  const Pair& p = rooms();
  std::map<RoomId, RoomPtr> held{{p.a->room.id, p.a}, {p.b->room.id, p.b}};
  auto lookup = [&](RoomId id) -> RoomPtr {
    auto it = held.find(id);
    return it == held.end() ? nullptr : it->second;
  };
  PlayerVerifier v;
  VerifyReport r;
  v.check(*p.a, lookup, r);
  v.check(*p.b, lookup, r);
  v.check(*p.a, lookup, r);  // received again (after an eviction): its seam is not re-checked
  EXPECT_EQ(r.rooms_checked, 3u);
  EXPECT_EQ(r.seams_checked, 1u);
  EXPECT_EQ(r.failures(), 0u) << (r.first_failures.empty() ? "" : r.first_failures[0]);
}

TEST(Verifier, a_moved_rim_vertex_is_a_seam_failure_on_the_checking_thread) {
  const Pair& p = rooms();
  auto bad = std::make_shared<ReadyRoom>(*p.b);
  const RoomId a_id = p.a->room.id;
  int slot = -1;
  for (size_t i = 0; i < bad->room.portals.size(); ++i)
    if (bad->room.portals[i].neighbour == a_id) slot = static_cast<int>(i);
  ASSERT_GE(slot, 0);
  bool moved = false;
  for (size_t v = 0; v < bad->mesh.vertex_count() && !moved; ++v) {
    if (bad->mesh.rim_portal[v] == slot) {
      bad->mesh.positions[v].x += 1.0f / 256.0f;  // one grid step
      moved = true;
    }
  }
  ASSERT_TRUE(moved);
  Verifier verifier(1, [&](int player, RoomId id) -> RoomPtr {
    EXPECT_EQ(player, 0);
    return id == a_id ? p.a : nullptr;
  });
  verifier.push(0, p.a);
  verifier.push(0, bad);
  VerifyReport r = verifier.finish();
  EXPECT_TRUE(r.enabled);
  EXPECT_EQ(r.rooms_checked, 2u);
  EXPECT_EQ(r.seams_checked, 1u);
  EXPECT_EQ(r.seam_failures, 1u);
  ASSERT_FALSE(r.first_failures.empty());
  EXPECT_EQ(verifier.finish().seam_failures, 1u);  // idempotent
}

TEST(Verifier, a_portal_that_disagrees_with_its_neighbour_is_a_graph_failure) {
  const Pair& p = rooms();
  auto bad = std::make_shared<ReadyRoom>(*p.b);
  for (auto& portal : bad->room.portals)
    if (portal.neighbour == p.a->room.id) portal.radius *= 0.5;
  PlayerVerifier v;
  VerifyReport r;
  auto none = [](RoomId) -> RoomPtr { return nullptr; };
  v.check(*p.a, none, r);
  v.check(*bad, none, r);
  EXPECT_EQ(r.graph_failures, 1u);
  EXPECT_EQ(r.seams_checked, 0u);
}

}  // namespace
