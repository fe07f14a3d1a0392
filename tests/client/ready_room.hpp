// A room as a client holds it after its frame, for the client tests: the layout's descriptor
// and the mesh through encode_room and decode_room with the frame's limits.
#pragma once

#include <gtest/gtest.h>

#include <utility>

#include "cave/layout.hpp"
#include "client/stream/room_store.hpp"
#include "codec/room_codec.hpp"
#include "mesh/room_mesh.hpp"

namespace grotto::client::test {

inline ReadyRoom ready_room(const mesh::RoomMesh& m, const cave::Room& r) {
  ReadyRoom out;
  out.room = r;
  out.lod = m.lod == mesh::Lod::kPatch ? 0 : 1;
  out.origin = m.origin;
  auto bytes = codec::encode_room(m);
  EXPECT_TRUE(bytes.ok()) << r.id.to_string();
  codec::DecodeLimits limits = out.lod == 0 ? codec::DecodeLimits{} : codec::kDetailLimits;
  limits.portal_count = static_cast<int>(r.portals.size());
  auto decoded = codec::decode_room(bytes.value(), limits);
  EXPECT_TRUE(decoded.ok()) << r.id.to_string();
  out.mesh = std::move(decoded).value();
  out.payload_bytes = bytes.value().size();
  return out;
}

}  // namespace grotto::client::test
