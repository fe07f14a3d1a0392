#include "server/extras.hpp"

#include <cinttypes>
#include <cstdio>
#include <vector>

#include "common/cave/lights.hpp"
#include "common/codec/room_codec.hpp"
#include "common/formations/formations.hpp"
#include "proto/lod.hpp"
#include "proto/messages.hpp"
#include "proto/room_frame.hpp"

namespace grotto::server {
namespace {

void append_number(std::string& out, double v, bool single) {
  char buf[40];
  std::snprintf(buf, sizeof buf, single ? "%.9g" : "%.17g", v);
  out += buf;
}

void append_vec3(std::string& out, Vec3 v) {
  out += '[';
  append_number(out, v.x, false);
  out += ',';
  append_number(out, v.y, false);
  out += ',';
  append_number(out, v.z, false);
  out += ']';
}

}  // namespace

Result<std::string> room_extras_json(std::span<const uint8_t> bytes, uint64_t seed,
                                     const cave::LayoutParams& layout) {
  proto::Limits limits;
  limits.max_frame_bytes = static_cast<uint32_t>(bytes.size());
  limits.max_lod = 255;
  auto frame = proto::decode_room_frame(bytes, limits);
  if (!frame) return frame.error();
  codec::DecodeLimits decode = proto::mesh_lod(frame->lod) == mesh::Lod::kDetail
                                   ? codec::kDetailLimits
                                   : codec::DecodeLimits{};
  decode.portal_count = static_cast<int>(frame->room.portals.size());
  decode.normals = frame->version == 1;
  auto mesh = codec::decode_room(frame->payload, decode);
  if (!mesh) return mesh.error();
  if (!decode.normals) {
    std::vector<codec::PortalDisc> discs;
    for (const cave::Portal& p : frame->room.portals)
      discs.push_back({p.centre, p.normal});
    if (Status s = codec::derive_normals(mesh.value(), frame->origin, discs); !s) return s.error();
  }
  const cave::Room& room = frame->room;

  std::string out = "{\"room\":\"" + room.id.to_string() + "\",\"origin\":";
  append_vec3(out, frame->origin);
  out += ",\"lights\":[";
  bool first = true;
  for (const cave::WorldLight& w : cave::room_lights(seed, layout, room)) {
    if (!first) out += ',';
    first = false;
    out += "{\"kind\":\"";
    out += cave::light_kind_name(w.kind);
    out += "\",\"position\":";
    append_vec3(out, w.position);
    out += ",\"colour\":";  // linear RGB x intensity at 1 m, as the renderer takes it
    append_vec3(out, w.colour * w.intensity);
    out += ",\"range\":";
    append_number(out, w.range, false);
    out += ",\"size\":";
    append_number(out, w.size, false);
    out += ",\"source_radius\":";
    append_number(out, cave::light_source_radius(w), false);
    out += ",\"glow\":" + std::to_string(static_cast<int>(w.kind));  // lights.glsl's GLOW_*
    out += ",\"seed\":";
    append_number(out, cave::light_pattern_seed(w.position), true);
    out += ",\"bound_centre\":";
    append_vec3(out, room.sphere.centre);
    out += ",\"bound_radius\":";
    append_number(out, cave::light_bound_radius(room), false);
    out += '}';
  }
  const std::vector<formations::FormationShape> placed =
      formations::place(formations::surface_of(*mesh, frame->origin, room.sphere.radius));
  out += "],\"formations\":{\"count\":" + std::to_string(placed.size()) + ",\"data\":[";
  first = true;
  for (const formations::FormationShape& f : placed) {
    const float v[16] = {f.root.x, f.root.y, f.root.z, f.length,
                         f.radius, f.tip,    f.embed,  static_cast<float>(f.kind),
                         f.taper,  f.flare,  f.rings,  f.bulbs,
                         f.seed,   f.yaw,    f.tint,   f.wet};
    for (float x : v) {
      if (!first) out += ',';
      first = false;
      append_number(out, x, true);
    }
  }
  out += "]}}\n";
  return out;
}

}  // namespace grotto::server
