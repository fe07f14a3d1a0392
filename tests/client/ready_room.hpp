// A room as a client holds it after its frame, for the client tests: the layout's descriptor
// and the mesh through encode_room and the client's own decoding (decode_payload) of a frame of
// the newest protocol version, normals derived on the client.
#pragma once

#include <gtest/gtest.h>

#include <utility>

#include "client/stream/conversation.hpp"
#include "client/stream/room_store.hpp"
#include "common/cave/layout.hpp"
#include "common/codec/room_codec.hpp"
#include "common/mesh/room_mesh.hpp"

namespace grotto::stream::test {

inline ReadyRoom ready_room(const mesh::RoomMesh& m, const cave::Room& r) {
  ReadyRoom out;
  out.room = r;
  out.lod = m.lod == mesh::Lod::kPatch ? 0 : 1;
  out.origin = m.origin;
  codec::EncodeOptions options;
  options.normals = proto::payload_has_normals(proto::kProtocolVersion);
  auto bytes = codec::encode_room(m, options);
  EXPECT_TRUE(bytes.ok()) << r.id.to_string();
  DecodeRoom job;
  job.frame.version = proto::kProtocolVersion;
  job.frame.room = r;
  job.frame.lod = out.lod;
  job.frame.origin = m.origin;
  job.frame.payload = bytes.value();
  job.limits = out.lod == 0 ? codec::DecodeLimits{} : codec::kDetailLimits;
  job.limits.portal_count = static_cast<int>(r.portals.size());
  job.limits.normals = options.normals;
  auto decoded = decode_payload(job);
  EXPECT_TRUE(decoded.ok()) << r.id.to_string();
  out.mesh = std::move(decoded).value();
  out.payload_bytes = bytes.value().size();
  return out;
}

}  // namespace grotto::stream::test
