// The native decoder's reading of a room frame's rims, for the browser viewer's test
// (web/e2e/viewer.e2e.mjs): the viewer must decode every rim vertex to the same world position,
// bit for bit (proto/PROTOCOL.md, "Rims" and "World coordinates").
//   rim_reference FRAME_FILE
// prints {"room": id, "rims": [[[x, y, z] by loop index] by portal slot]}: origin + offset in
// binary64, each number with 17 significant digits (it round-trips). Exit 1 with a one-line
// reason when the frame or its payload does not decode.
#include <cstdio>
#include <fstream>
#include <iterator>
#include <string>
#include <vector>

#include "common/codec/room_codec.hpp"
#include "proto/room_frame.hpp"

int main(int argc, char** argv) {
  using namespace grotto;
  if (argc != 2) {
    std::fprintf(stderr, "usage: rim_reference FRAME_FILE\n");
    return 2;
  }
  std::ifstream in(argv[1], std::ios::binary);
  std::vector<uint8_t> bytes((std::istreambuf_iterator<char>(in)), {});
  proto::Limits limits;
  auto frame = proto::decode_room_frame(bytes, limits);
  if (!frame) {
    std::fprintf(stderr, "rim_reference: %s\n", frame.error().message.c_str());
    return 1;
  }
  codec::DecodeLimits decode;
  decode.portal_count = static_cast<int>(frame->room.portals.size());
  decode.normals = frame->version == 1;
  auto mesh = codec::decode_room(frame->payload, decode);
  if (!mesh) {
    std::fprintf(stderr, "rim_reference: %s\n", mesh.error().message.c_str());
    return 1;
  }
  std::vector<std::vector<std::string>> rims(frame->room.portals.size());
  for (size_t i = 0; i < mesh->positions.size(); ++i) {
    const int slot = mesh->rim_portal[i];
    if (slot < 0) continue;
    auto& loop = rims[static_cast<size_t>(slot)];
    const size_t k = mesh->rim_index[i];
    if (loop.size() <= k) loop.resize(k + 1);
    char text[128];
    std::snprintf(text, sizeof text, "[%.17g,%.17g,%.17g]",
                  frame->origin.x + static_cast<double>(mesh->positions[i].x),
                  frame->origin.y + static_cast<double>(mesh->positions[i].y),
                  frame->origin.z + static_cast<double>(mesh->positions[i].z));
    loop[k] = text;
  }
  std::printf("{\"room\":\"%s\",\"rims\":[", frame->room.id.to_string().c_str());
  for (size_t s = 0; s < rims.size(); ++s) {
    std::printf("%s[", s ? "," : "");
    for (size_t k = 0; k < rims[s].size(); ++k)
      std::printf("%s%s", k ? "," : "", rims[s][k].empty() ? "null" : rims[s][k].c_str());
    std::printf("]");
  }
  std::printf("]}\n");
  return 0;
}
