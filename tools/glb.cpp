#include "tools/glb.hpp"

#include <unistd.h>
#include <algorithm>
#include <bit>
#include <cassert>
#include <cerrno>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <nlohmann/json.hpp>
#include <thread>
#include <utility>

#include "common/codec/room_codec.hpp"
#include "common/core/bytes.hpp"
#include "common/core/parallel.hpp"
#include "common/formations/formations.hpp"
#include "proto/layout_json.hpp"

namespace grotto::tools {
namespace {

// Key order as written, so the file reads asset first.
using json = nlohmann::ordered_json;

// glTF 2.0 enums (spec §5.1.3 accessor.componentType, §5.11.4 bufferView.target,
// §5.24.4 primitive.mode).
constexpr int kUnsignedShort = 5123;
constexpr int kUnsignedInt = 5125;
constexpr int kFloat = 5126;
constexpr int kArrayBuffer = 34962;
constexpr int kElementArrayBuffer = 34963;
constexpr int kTriangles = 4;

// The GLB container (spec §4.4): a 12-byte header, then chunks of (length, type, data), each
// data padded to 4 bytes: JSON with spaces, BIN with zeros.
constexpr uint32_t kGlbMagic = 0x46546C67;  // "glTF"
constexpr uint32_t kGlbVersion = 2;
constexpr uint32_t kChunkJson = 0x4E4F534A;  // "JSON"
constexpr uint32_t kChunkBin = 0x004E4942;   // "BIN\0"

constexpr const char* kDraco = "KHR_draco_mesh_compression";
constexpr const char* kLights = "KHR_lights_punctual";

json vec3(Vec3 v) {
  return json::array({v.x, v.y, v.z});
}
json sector(cave::SectorCoord s) {
  return json::array({s.x, s.y, s.z});
}

void append_f32(std::vector<uint8_t>& out, float v) {
  le::append(out, std::bit_cast<uint32_t>(v), 4);
}

// The binary chunk with its bufferViews and accessors, built together.
struct Document {
  std::vector<uint8_t> bin;
  json buffer_views = json::array();
  json accessors = json::array();

  // A bufferView over `bytes`, starting on a 4-byte boundary: vertex elements must be 4-byte
  // aligned (spec §3.6.2.4) and this also aligns every component type. target 0: none (the
  // Draco payload, which only the extension reads).
  size_t add_view(std::span<const uint8_t> bytes, int target) {
    while (bin.size() % 4 != 0)
      bin.push_back(0);
    json view = {{"buffer", 0}, {"byteOffset", bin.size()}, {"byteLength", bytes.size()}};
    if (target != 0) view["target"] = target;
    bin.insert(bin.end(), bytes.begin(), bytes.end());
    buffer_views.push_back(std::move(view));
    return buffer_views.size() - 1;
  }

  // A tightly packed accessor over a whole bufferView of its own.
  size_t add_accessor(std::span<const uint8_t> bytes, int target, int component_type, size_t count,
                      const char* type) {
    size_t view = add_view(bytes, target);
    accessors.push_back({{"bufferView", view},
                         {"componentType", component_type},
                         {"count", count},
                         {"type", type}});
    return accessors.size() - 1;
  }
};

// One room's mesh as the server would stream it (a Draco payload) and that payload decoded, so
// the plain accessors hold the same vertices in the same order as the payload.
struct CodedRoom {
  std::vector<uint8_t> payload;
  codec::DecodedRoom decoded;
};
Result<CodedRoom> code_room(const cave::Room& room, const mesh::RoomMesh& m, mesh::Lod lod) {
  const std::string id = room.id.to_string();
  Result<std::vector<uint8_t>> payload = codec::encode_room(m);  // the server's options
  if (!payload)
    return invalid_argument("room " + id + " cannot be encoded: " + payload.error().message);
  codec::DecodeLimits limits =
      lod == mesh::Lod::kDetail ? codec::kDetailLimits : codec::DecodeLimits{};
  limits.portal_count = static_cast<int>(room.portals.size());
  Result<codec::DecodedRoom> decoded = codec::decode_room(*payload, limits);
  if (!decoded) {
    return invalid_argument("room " + id +
                            "'s payload does not decode: " + decoded.error().message);
  }
  return CodedRoom{std::move(payload).value(), std::move(decoded).value()};
}

// A room's coded mesh into the document's buffer: the Draco view and plain accessors. Returns
// the mesh's JSON.
json add_room_mesh(Document& doc, const cave::Room& room, const CodedRoom& coded) {
  const std::string id = room.id.to_string();
  const codec::DecodedRoom& d = coded.decoded;
  const size_t n = d.vertex_count();
  assert(n > 0);  // decode_room refuses a payload without triangles

  size_t draco_view = doc.add_view(coded.payload, 0);

  std::vector<uint8_t> bytes;
  bytes.reserve(n * 12);
  constexpr double kInf = std::numeric_limits<double>::infinity();
  Vec3 lo{kInf, kInf, kInf}, hi{-kInf, -kInf, -kInf};
  for (const mesh::core::float3& p : d.positions) {
    append_f32(bytes, p.x);
    append_f32(bytes, p.y);
    append_f32(bytes, p.z);
    lo = {std::min<double>(lo.x, p.x), std::min<double>(lo.y, p.y), std::min<double>(lo.z, p.z)};
    hi = {std::max<double>(hi.x, p.x), std::max<double>(hi.y, p.y), std::max<double>(hi.z, p.z)};
  }
  size_t position = doc.add_accessor(bytes, kArrayBuffer, kFloat, n, "VEC3");
  // The spec requires POSITION's bounds; doubles of float values print back to the same floats.
  doc.accessors[position]["min"] = vec3(lo);
  doc.accessors[position]["max"] = vec3(hi);

  bytes.clear();
  for (const mesh::core::float3& v : d.normals) {
    append_f32(bytes, v.x);
    append_f32(bytes, v.y);
    append_f32(bytes, v.z);
  }
  size_t normal = doc.add_accessor(bytes, kArrayBuffer, kFloat, n, "VEC3");

  bytes.clear();
  for (size_t i = 0; i < n; ++i) {
    append_f32(bytes, d.roughness[i]);
    append_f32(bytes, d.mineral[i]);
  }
  size_t channels = doc.add_accessor(bytes, kArrayBuffer, kFloat, n, "VEC2");

  // The payload's own rim values: portal slot + 1 (0 off rims), index on the canonical loop.
  bytes.clear();
  for (size_t i = 0; i < n; ++i) {
    le::append(bytes, static_cast<uint16_t>(d.rim_portal[i] + 1), 2);
    le::append(bytes, d.rim_index[i], 2);
  }
  size_t rim = doc.add_accessor(bytes, kArrayBuffer, kUnsignedShort, n, "VEC2");

  bytes.clear();
  const bool wide = n >= 65536;  // UNSIGNED_SHORT holds every index below 65,536
  for (uint32_t index : d.indices)
    le::append(bytes, index, wide ? 4 : 2);
  size_t indices = doc.add_accessor(
      bytes, kElementArrayBuffer, wide ? kUnsignedInt : kUnsignedShort, d.indices.size(), "SCALAR");

  json draco = {{"bufferView", draco_view},
                {"attributes",
                 {{"POSITION", codec::kPositionId},
                  {"NORMAL", codec::kNormalId},
                  {kChannelsAttribute, codec::kChannelsId},
                  {kRimAttribute, codec::kRimId}}}};
  json primitive = {{"attributes",
                     {{"POSITION", position},
                      {"NORMAL", normal},
                      {kChannelsAttribute, channels},
                      {kRimAttribute, rim}}},
                    {"indices", indices},
                    {"material", 0},
                    {"mode", kTriangles},
                    {"extensions", {{kDraco, std::move(draco)}}}};
  return json{{"name", id}, {"primitives", json::array({std::move(primitive)})}};
}

// A mesh of one triangle primitive from plain arrays (positions in its node's frame): POSITION,
// NORMAL and indices, with material `material`.
json add_plain_mesh(Document& doc, const std::string& name, std::span<const glm::vec3> positions,
                    std::span<const glm::vec3> normals, std::span<const uint32_t> indices,
                    int material) {
  std::vector<uint8_t> bytes;
  constexpr double kInf = std::numeric_limits<double>::infinity();
  Vec3 lo{kInf, kInf, kInf}, hi{-kInf, -kInf, -kInf};
  for (const glm::vec3& p : positions) {
    append_f32(bytes, p.x);
    append_f32(bytes, p.y);
    append_f32(bytes, p.z);
    lo = {std::min<double>(lo.x, p.x), std::min<double>(lo.y, p.y), std::min<double>(lo.z, p.z)};
    hi = {std::max<double>(hi.x, p.x), std::max<double>(hi.y, p.y), std::max<double>(hi.z, p.z)};
  }
  const size_t position = doc.add_accessor(bytes, kArrayBuffer, kFloat, positions.size(), "VEC3");
  doc.accessors[position]["min"] = vec3(lo);
  doc.accessors[position]["max"] = vec3(hi);
  bytes.clear();
  for (const glm::vec3& n : normals) {
    append_f32(bytes, n.x);
    append_f32(bytes, n.y);
    append_f32(bytes, n.z);
  }
  const size_t normal = doc.add_accessor(bytes, kArrayBuffer, kFloat, normals.size(), "VEC3");
  bytes.clear();
  for (uint32_t index : indices)
    le::append(bytes, index, 4);
  const size_t index =
      doc.add_accessor(bytes, kElementArrayBuffer, kUnsignedInt, indices.size(), "SCALAR");
  json primitive = {{"attributes", {{"POSITION", position}, {"NORMAL", normal}}},
                    {"indices", index},
                    {"material", material},
                    {"mode", kTriangles}};
  return json{{"name", name}, {"primitives", json::array({std::move(primitive)})}};
}

// One formation's shape as the file's extras give it (formations::FormationShape: root in its
// room's frame, metres and radians).
json formation_json(const formations::FormationShape& f) {
  static constexpr const char* kKinds[] = {"stalactite", "stalagmite", "column", "drapery",
                                           "boulder"};
  return {{"kind", kKinds[std::clamp(f.kind, 0, 4)]},
          {"root", {f.root.x, f.root.y, f.root.z}},
          {"length", f.length},
          {"radius", f.radius},
          {"tip", f.tip},
          {"embed", f.embed},
          {"taper", f.taper},
          {"flare", f.flare},
          {"rings", f.rings},
          {"bulbs", f.bulbs},
          {"seed", f.seed},
          {"yaw", f.yaw},
          {"colour",
           [&] {
             const glm::vec3 c = formations::formation_srgb(f.tint);
             return json{c.r, c.g, c.b};
           }()},
          {"wet", f.wet}};
}

void append_chunk(std::vector<uint8_t>& out, uint32_t type, std::span<const uint8_t> data,
                  uint8_t pad) {
  size_t padded = (data.size() + 3) / 4 * 4;
  le::append(out, padded, 4);
  le::append(out, type, 4);
  out.insert(out.end(), data.begin(), data.end());
  out.resize(out.size() + (padded - data.size()), pad);
}

}  // namespace

Result<std::vector<uint8_t>> region_glb(const GlbSource& source, std::span<const GlbRoom> rooms) {
  Document doc;
  json nodes = json::array(), meshes = json::array(), scene_nodes = json::array();
  json light_defs = json::array(), child_nodes = json::array();
  bool calcite = false;  // a formations mesh's speleothems use the second material
  // The meshes encoded and decoded on every hardware thread (each room's alone), a window of
  // rooms at a time so that only the window's decoded meshes are held, then laid into the buffer
  // in the rooms' order.
  constexpr size_t kWindow = 64;
  const int threads = static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));
  std::vector<Result<CodedRoom>> coded;
  for (size_t i = 0; i < rooms.size(); ++i) {
    if (i % kWindow == 0) {
      coded.assign(std::min(kWindow, rooms.size() - i), invalid_argument("no mesh"));
      for_each_index(coded.size(), threads, [&](size_t k) {
        assert(rooms[i + k].room != nullptr);
        if (const GlbRoom& r = rooms[i + k]; r.mesh != nullptr)
          coded[k] = code_room(*r.room, *r.mesh, source.lod);
      });
    }
    Result<CodedRoom>& room_coded = coded[i % kWindow];
    const GlbRoom& r = rooms[i];
    // The portals as `grotto-layout --room` prints them: one view of a room (proto/).
    json extras = json::parse(
        source.world ? proto::room_json(*source.world, *r.room) : proto::room_json(*r.room),
        nullptr, false);
    assert(!extras.is_discarded());
    json node = {{"name", r.room->id.to_string()}};
    Vec3 parent = source.anchor;  // where the node's frame is, world metres
    if (r.mesh != nullptr) {
      if (!room_coded) return room_coded.error();
      json mesh = add_room_mesh(doc, *r.room, *room_coded);
      Vec3 t = r.mesh->origin - source.anchor;
      node["translation"] = vec3(t);
      parent = r.mesh->origin;
      node["mesh"] = meshes.size();
      meshes.push_back(std::move(mesh));
    } else {
      extras["mesh_error"] = r.mesh_error;
    }
    node["extras"] = std::move(extras);
    // Light nodes go after every room's (rooms keep the indices of the region's order).
    json children = json::array();
    for (size_t k = 0; k < r.lights.size(); ++k) {
      const cave::WorldLight& l = r.lights[k];
      const std::string kind = cave::light_kind_name(l.kind);
      children.push_back(rooms.size() + child_nodes.size());
      child_nodes.push_back({{"name", r.room->id.to_string() + ".light" + std::to_string(k)},
                             {"translation", vec3(l.position - parent)},
                             {"extensions", {{kLights, {{"light", light_defs.size()}}}}},
                             {"extras",
                              {{"kind", kind},
                               {"facing", vec3(l.facing)},
                               {"size", l.size},
                               {"source_radius", cave::light_source_radius(l)},
                               {"room", r.room->id.to_string()}}}});
      light_defs.push_back({{"name", kind},
                            {"type", "point"},
                            {"color", vec3(l.colour)},
                            {"intensity", l.intensity},
                            {"range", l.range}});
    }
    // The room's formations (formations::place over its mesh as decoded, what a client places
    // them over): one child node with them all as one mesh, and each instance's shape in extras.
    // The speleothems are one primitive in the calcite material, a hall's fallen blocks another
    // in the rock's (they are the walls' limestone, as room.frag shades them).
    if (r.mesh != nullptr && source.formations) {
      const std::vector<formations::FormationShape> placed = formations::place(
          formations::surface_of(room_coded->decoded, r.mesh->origin, r.room->sphere.radius));
      if (!placed.empty()) {
        struct Part {
          std::vector<glm::vec3> positions, normals;
          std::vector<uint32_t> indices;
        } dripstone, blocks;
        json shapes = json::array();
        for (const formations::FormationShape& f : placed) {
          Part& part = f.kind == formations::kFormationBoulder ? blocks : dripstone;
          formations::append_mesh(f, kGlbFormationLod, part.positions, part.normals, part.indices);
          shapes.push_back(formation_json(f));
        }
        children.push_back(rooms.size() + child_nodes.size());
        child_nodes.push_back({{"name", r.room->id.to_string() + ".formations"},
                               {"mesh", meshes.size()},
                               {"extras", {{"formations", std::move(shapes)}}}});
        const std::string name = r.room->id.to_string() + ".formations";
        json mesh;
        for (const auto& [part, material] : {std::pair{&dripstone, 1}, std::pair{&blocks, 0}}) {
          if (part->indices.empty()) continue;
          json one =
              add_plain_mesh(doc, name, part->positions, part->normals, part->indices, material);
          if (mesh.is_null())
            mesh = std::move(one);
          else
            mesh["primitives"].push_back(std::move(one["primitives"][0]));
          calcite = calcite || material == 1;
        }
        meshes.push_back(std::move(mesh));
      }
    }
    if (!children.empty()) node["children"] = std::move(children);
    scene_nodes.push_back(nodes.size());
    nodes.push_back(std::move(node));
  }

  json doc_json = {{"asset", {{"version", "2.0"}, {"generator", source.generator}}}};
  // Used, not required: every primitive also has plain accessors, for readers without Draco.
  json used = json::array();
  if (!meshes.empty()) used.push_back(kDraco);
  if (!light_defs.empty()) {
    used.push_back(kLights);
    doc_json["extensions"] = {{kLights, {{"lights", std::move(light_defs)}}}};
  }
  for (json& c : child_nodes)
    nodes.push_back(std::move(c));
  if (!used.empty()) doc_json["extensionsUsed"] = std::move(used);
  json scene = {{"name", "grotto seed " + std::to_string(source.seed)}};
  if (!scene_nodes.empty()) scene["nodes"] = std::move(scene_nodes);
  // Seed as text: JSON readers that hold numbers as doubles lose 64-bit integers.
  scene["extras"] = {{"seed", std::to_string(source.seed)}, {"sector_size", source.sector_size},
                     {"from", sector(source.lo)},           {"to", sector(source.hi)},
                     {"lod", mesh::lod_name(source.lod)},   {"anchor", vec3(source.anchor)}};
  doc_json["scene"] = 0;
  doc_json["scenes"] = json::array({std::move(scene)});
  // glTF arrays may not be empty: a region whose rooms all failed has nodes only.
  if (!nodes.empty()) doc_json["nodes"] = std::move(nodes);
  if (!meshes.empty()) {
    doc_json["meshes"] = std::move(meshes);
    // Grotto's triangles face into the cave (counter-clockwise seen from inside): single-sided,
    // so a camera inside sees the walls and one outside looks through the near walls.
    doc_json["materials"] = json::array({{{"name", "rock"},
                                          {"pbrMetallicRoughness",
                                           {{"baseColorFactor", {0.55, 0.50, 0.45, 1.0}},
                                            {"metallicFactor", 0.0},
                                            {"roughnessFactor", 0.9}}}}});
    if (calcite) {
      // Wet calcite, pale (room.frag's dripstone between its root and its tip).
      doc_json["materials"].push_back({{"name", "calcite"},
                                       {"pbrMetallicRoughness",
                                        {{"baseColorFactor", {0.70, 0.64, 0.54, 1.0}},
                                         {"metallicFactor", 0.0},
                                         {"roughnessFactor", 0.45}}}});
    }
    doc_json["accessors"] = std::move(doc.accessors);
    doc_json["bufferViews"] = std::move(doc.buffer_views);
    doc_json["buffers"] = json::array({{{"byteLength", doc.bin.size()}}});
  }

  const std::string text = doc_json.dump();
  const auto* text_bytes = reinterpret_cast<const uint8_t*>(text.data());
  size_t total = 12 + 8 + (text.size() + 3) / 4 * 4;
  if (!doc.bin.empty()) total += 8 + (doc.bin.size() + 3) / 4 * 4;
  if (total > std::numeric_limits<uint32_t>::max()) {
    return invalid_argument("the glb would be " + std::to_string(total) +
                            " bytes, over the format's 4 GiB");
  }
  std::vector<uint8_t> out;
  out.reserve(total);
  le::append(out, kGlbMagic, 4);
  le::append(out, kGlbVersion, 4);
  le::append(out, total, 4);
  append_chunk(out, kChunkJson, {text_bytes, text.size()}, ' ');
  if (!doc.bin.empty()) append_chunk(out, kChunkBin, doc.bin, 0);
  assert(out.size() == total);
  return out;
}

Status write_file_replacing(const std::string& path, std::span<const uint8_t> bytes) {
  namespace fs = std::filesystem;
  const fs::path target(path);
  // Beside the target, so the rename stays on one file system; the pid keeps two writers apart.
  std::string name = ".";  // appended: GCC 12 warns falsely (-Wrestrict) on "." + string
  name += target.filename().string();
  name += '.';
  name += std::to_string(::getpid());
  name += ".tmp";
  const fs::path temp = target.parent_path() / name;
  std::ofstream f(temp, std::ios::binary | std::ios::trunc);
  f.write(reinterpret_cast<const char*>(bytes.data()), static_cast<std::streamsize>(bytes.size()));
  f.close();
  std::error_code ec;
  if (!f) {
    const std::string why = std::strerror(errno);
    fs::remove(temp, ec);
    return Error{ErrorCode::kUnavailable, "cannot write " + path + ": " + why};
  }
  fs::rename(temp, target, ec);
  if (ec) {
    std::error_code ignored;
    fs::remove(temp, ignored);
    return Error{ErrorCode::kUnavailable, "cannot write " + path + ": " + ec.message()};
  }
  return {};
}

}  // namespace grotto::tools
