#include "common/codec/room_codec.hpp"

#include <draco/compression/config/compression_shared.h>
#include <draco/compression/expert_encode.h>
#include <draco/compression/mesh/mesh_edgebreaker_decoder.h>
#include <draco/mesh/mesh.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "common/core/grid.hpp"

namespace grotto::codec {
namespace {

using mesh::core::float3;

Error fail(std::string message) {
  return invalid_argument("room payload: " + std::move(message));
}

bool finite(float3 v) {
  return std::isfinite(v.x) && std::isfinite(v.y) && std::isfinite(v.z);
}
bool within_offset(float3 v) {
  return std::fabs(v.x) <= kMaxOffset && std::fabs(v.y) <= kMaxOffset &&
         std::fabs(v.z) <= kMaxOffset;
}
bool unit(float3 n) {
  float len = std::sqrt(n.x * n.x + n.y * n.y + n.z * n.z);
  return std::fabs(len - 1.0f) <= kNormalTolerance;
}
bool on_grid(float3 v, int step_log2) {
  return grid::on_grid(v.x, step_log2) && grid::on_grid(v.y, step_log2) &&
         grid::on_grid(v.z, step_log2);
}
bool in_unit_range(float v) {
  return v >= 0.0f && v <= 1.0f;  // false for NaN
}

std::string str(size_t v) {
  return std::to_string(v);
}

// The contracts of RoomView, checked before anything reaches Draco. The decoder checks the same
// rules, so a room that decodes always encodes again (the fuzzer holds us to that).
Status validate_view(const RoomView& r, int step_log2, bool normals) {
  const size_t n = r.positions.size();
  if ((normals && r.normals.size() != n) || r.roughness.size() != n || r.mineral.size() != n ||
      r.rim_portal.size() != n || r.rim_index.size() != n) {
    return fail("per-vertex arrays differ in length");
  }
  if (n < 3 || n > kMaxVertices) return fail(str(n) + " vertices, outside 3.." + str(kMaxVertices));
  if (r.indices.size() % 3 != 0) return fail("index count is not a multiple of 3");
  const size_t t = r.indices.size() / 3;
  if (t < 1 || t > kMaxTriangles) {
    return fail(str(t) + " triangles, outside 1.." + str(kMaxTriangles));
  }
  if (!grid::on_grid(r.origin.x, step_log2) || !grid::on_grid(r.origin.y, step_log2) ||
      !grid::on_grid(r.origin.z, step_log2)) {
    return fail("room origin is not on the encoder's grid");
  }
  for (size_t v = 0; v < n; ++v) {
    if (!finite(r.positions[v]) || !within_offset(r.positions[v])) {
      return fail("vertex " + str(v) + ": position not finite or beyond the room's frame");
    }
    if (normals && (!finite(r.normals[v]) || !unit(r.normals[v]))) {
      return fail("vertex " + str(v) + ": normal is not unit length");
    }
    if (!in_unit_range(r.roughness[v]) || !in_unit_range(r.mineral[v])) {
      return fail("vertex " + str(v) + ": channel outside [0, 1]");
    }
    if (r.rim_portal[v] < -1 || r.rim_portal[v] >= kMaxPortals) {
      return fail("vertex " + str(v) + ": rim slot " + std::to_string(r.rim_portal[v]) +
                  " out of range");
    }
    if (r.rim_portal[v] >= 0 && !on_grid(r.positions[v], step_log2)) {
      return fail("vertex " + str(v) + ": rim vertex is not on the encoder's grid");
    }
  }
  for (size_t i = 0; i < t; ++i) {
    uint32_t a = r.indices[3 * i], b = r.indices[3 * i + 1], c = r.indices[3 * i + 2];
    if (a >= n || b >= n || c >= n) return fail("triangle " + str(i) + ": index out of range");
    if (a == b || b == c || a == c) return fail("triangle " + str(i) + " is degenerate");
  }
  return {};
}

std::string exact_text(float v) {
  char text[40];
  std::snprintf(text, sizeof text, "%.17g", static_cast<double>(v));
  return text;
}

std::unique_ptr<draco::PointAttribute> make_attribute(draco::GeometryAttribute::Type type,
                                                      int components, draco::DataType data_type,
                                                      size_t count) {
  auto att = std::make_unique<draco::PointAttribute>();
  att->Init(type, static_cast<int8_t>(components), data_type, false, count);
  return att;
}

}  // namespace

RoomView view_of(const mesh::RoomMesh& m) {
  return {m.origin,  m.positions,  m.normals,   m.roughness,
          m.mineral, m.rim_portal, m.rim_index, m.indices};
}

RoomView view_of(const DecodedRoom& r, Vec3 origin) {
  return {origin,    r.positions,  r.normals,   r.roughness,
          r.mineral, r.rim_portal, r.rim_index, r.indices};
}

namespace {

// encode_room, or with `geometry_only` the same payload without the three non-position
// attributes (encode_geometry_only).
Result<std::vector<uint8_t>> encode(const RoomView& room, const EncodeOptions& options,
                                    bool geometry_only) {
  if (options.speed < 0 || options.speed > 9) return fail("encoder speed outside 0..9");
  if (options.normal_bits < 2 || options.normal_bits > 16) return fail("normal bits outside 2..16");
  if (options.channel_bits < 1 || options.channel_bits > 16) {
    return fail("channel bits outside 1..16");
  }
  if (options.grid_step_log2 < 0 || options.grid_step_log2 > grid::kWireStepLog2) {
    return fail("grid step outside 2^-" + str(grid::kWireStepLog2) + "..1 m");
  }
  const bool normals = options.normals && !geometry_only;
  if (Status s = validate_view(room, options.grid_step_log2, normals); !s) return s.error();

  const size_t n = room.positions.size();
  draco::Mesh dm;
  dm.set_num_points(static_cast<uint32_t>(n));
  for (size_t i = 0; i < room.indices.size(); i += 3) {
    dm.AddFace({draco::PointIndex(room.indices[i]), draco::PointIndex(room.indices[i + 1]),
                draco::PointIndex(room.indices[i + 2])});
  }

  auto pos = make_attribute(draco::GeometryAttribute::POSITION, 3, draco::DT_FLOAT32, n);
  auto nrm = make_attribute(draco::GeometryAttribute::NORMAL, 3, draco::DT_FLOAT32, n);
  auto chn = make_attribute(draco::GeometryAttribute::GENERIC, 2, draco::DT_FLOAT32, n);
  auto rim = make_attribute(draco::GeometryAttribute::GENERIC, 2, draco::DT_UINT16, n);
  std::array<double, 3> lo = {kMaxOffset, kMaxOffset, kMaxOffset};
  std::array<double, 3> hi = {-kMaxOffset, -kMaxOffset, -kMaxOffset};
  for (size_t v = 0; v < n; ++v) {
    const draco::AttributeValueIndex i(static_cast<uint32_t>(v));
    const float3 p = room.positions[v], q = normals ? room.normals[v] : float3{};
    const float pv[3] = {p.x, p.y, p.z}, nv[3] = {q.x, q.y, q.z};
    const float cv[2] = {room.roughness[v], room.mineral[v]};
    const int slot = room.rim_portal[v];
    const uint16_t rv[2] = {static_cast<uint16_t>(slot + 1),
                            static_cast<uint16_t>(slot >= 0 ? room.rim_index[v] : 0)};
    pos->SetAttributeValue(i, pv);
    nrm->SetAttributeValue(i, nv);
    chn->SetAttributeValue(i, cv);
    rim->SetAttributeValue(i, rv);
    for (int c = 0; c < 3; ++c) {
      lo[c] = std::min(lo[c], static_cast<double>(pv[c]));
      hi[c] = std::max(hi[c], static_cast<double>(pv[c]));
    }
  }
  const int pos_id = dm.AddAttribute(std::move(pos));
  dm.attribute(pos_id)->set_unique_id(kPositionId);
  int nrm_id = -1, chn_id = -1;
  if (normals) {
    nrm_id = dm.AddAttribute(std::move(nrm));
    dm.attribute(nrm_id)->set_unique_id(kNormalId);
  }
  if (!geometry_only) {
    chn_id = dm.AddAttribute(std::move(chn));
    const int rim_id = dm.AddAttribute(std::move(rim));
    dm.attribute(chn_id)->set_unique_id(kChannelsId);
    dm.attribute(rim_id)->set_unique_id(kRimId);
  }

  // The world grid as Draco's quantizer: Draco dequantizes q * (range / (2^bits - 1)) + origin in
  // float32, so range = (2^bits - 1) * step makes the step exactly `step` (a power of two, the
  // division is exact) and a grid-multiple origin keeps every grid value exact; offsets below
  // grid::kFrameSize keep the sum exact too. Encoding computes (v - origin) / step and rounds,
  // which is exact for grid values, so grid points travel without loss.
  const double step = 1.0 / static_cast<double>(1 << options.grid_step_log2);
  float origin[3];
  double extent = 0;
  for (int c = 0; c < 3; ++c) {
    origin[c] = static_cast<float>(std::floor(lo[c] / step) * step);
    extent = std::max(extent, hi[c] - origin[c]);
  }
  int bits = 1;
  while (static_cast<double>((uint32_t{1} << bits) - 1) * step < extent)
    ++bits;
  const float range = static_cast<float>(((uint32_t{1} << bits) - 1) * step);
  // Channels on [0, 1] explicitly: Draco's own range would follow the data (min/max per room),
  // and a dequantized 1 would not be exactly 1 in every room.
  const float channel_origin[2] = {0.0f, 0.0f};

  draco::ExpertEncoder encoder(dm);
  encoder.SetEncodingMethod(draco::MESH_EDGEBREAKER_ENCODING);
  encoder.SetSpeedOptions(options.speed, options.speed);
  // Every attribute has one value per point, so no attribute has a seam: one connectivity serves
  // them all. Below speed 6 Draco would still build and encode a seam table per non-position
  // attribute (MeshAttributeCornerTable::InitFromAttribute on both sides), ~30% of the encode
  // and over 25% of the decode of a patch room for nothing (docs/BENCHMARKS.md, "Room codec"). With
  // one connectivity the payload has one attribute decoder holding all four attributes and no
  // attribute tables, which every Draco decoder reads.
  encoder.options().SetGlobalBool("split_mesh_on_seams", true);
  // Draco uses the plain edgebreaker for meshes under 1,000 triangles, whatever the speed; the
  // valence coder it uses above that (speed < 5) makes a median patch room's positions and
  // connectivity ~10% smaller (~100 bytes) for ~0.01 ms more encoding.
  if (options.speed < 5) {
    encoder.options().SetGlobalInt("edgebreaker_method", draco::MESH_EDGEBREAKER_VALENCE_ENCODING);
  }
  encoder.SetAttributeExplicitQuantization(pos_id, bits, 3, origin, range);
  // Draco keeps options as text written with std::to_string (six decimals), which would turn
  // the range 2047/256 into 7.996094 and the step into no power of two. Grid values are dyadic
  // with few digits, so "%.17g" writes them exactly and strtof reads them back exactly.
  draco::Options exact = *encoder.options().FindAttributeOptions(pos_id);
  exact.SetString("quantization_origin", exact_text(origin[0]) + " " + exact_text(origin[1]) + " " +
                                             exact_text(origin[2]));
  exact.SetString("quantization_range", exact_text(range));
  encoder.options().SetAttributeOptions(pos_id, exact);
  if (normals) encoder.SetAttributeQuantization(nrm_id, options.normal_bits);
  if (!geometry_only) {
    encoder.SetAttributeExplicitQuantization(chn_id, options.channel_bits, 2, channel_origin, 1.0f);
  }
  draco::EncoderBuffer buffer;
  draco::Status status = encoder.EncodeToBuffer(&buffer);
  if (!status.ok()) {
    return Error{ErrorCode::kInternal, "room payload: Draco encoder: " + status.error_msg_string()};
  }
  if (buffer.size() > kMaxPayloadBytes) {
    return fail(str(buffer.size()) + " bytes, over the format's " + str(kMaxPayloadBytes));
  }
  const auto* data = reinterpret_cast<const uint8_t*>(buffer.data());
  return std::vector<uint8_t>(data, data + buffer.size());
}

}  // namespace

Result<std::vector<uint8_t>> encode_room(const RoomView& room, const EncodeOptions& options) {
  return encode(room, options, false);
}

Result<std::vector<uint8_t>> encode_geometry_only(const RoomView& room,
                                                  const EncodeOptions& options) {
  return encode(room, options, true);
}

namespace {

// Reads Draco's unsigned varint (7 bits a byte, least significant group first) as
// draco::DecodeVarint does; refuses more than 5 bytes, which Draco would silently wrap.
bool read_varint(std::span<const uint8_t> in, size_t& at, uint64_t& out) {
  out = 0;
  for (int i = 0; i < 5; ++i) {
    if (at >= in.size()) return false;
    const uint8_t b = in[at++];
    out |= static_cast<uint64_t>(b & 0x7f) << (7 * i);
    if ((b & 0x80) == 0) return true;
  }
  return false;
}

// Draco sizes its connectivity tables from counts in the stream before it knows whether the
// stream holds that much (CornerTable::Reset(num_faces) with up to 1.4 billion faces), so the
// header is read here first (draco/compression/point_cloud/point_cloud_decoder.cc,
// mesh/mesh_edgebreaker_decoder_impl.cc, bitstream 2.2) and the counts are bounded. Only what
// encode_room writes is accepted: a 2.2 edgebreaker mesh without metadata.
Status check_header(std::span<const uint8_t> in, const DecodeLimits& limits) {
  constexpr size_t kHeader = 11;  // "DRACO", major, minor, encoder type, method, flags (u16)
  if (in.size() < kHeader + 1) return fail("truncated Draco header");
  if (std::memcmp(in.data(), "DRACO", 5) != 0) return fail("not a Draco payload (bad magic)");
  if (in[5] != draco::kDracoMeshBitstreamVersionMajor ||
      in[6] != draco::kDracoMeshBitstreamVersionMinor) {
    return fail("Draco bitstream version " + str(in[5]) + "." + str(in[6]) + ", expected " +
                str(draco::kDracoMeshBitstreamVersionMajor) + "." +
                str(draco::kDracoMeshBitstreamVersionMinor));
  }
  if (in[7] != draco::TRIANGULAR_MESH) return fail("Draco payload is not a triangle mesh");
  if (in[8] != draco::MESH_EDGEBREAKER_ENCODING) return fail("Draco payload is not edgebreaker");
  if (in[9] != 0 || in[10] != 0) return fail("unexpected Draco header flags (metadata)");
  size_t at = kHeader + 1;  // the traversal decoder type; Draco checks its value
  uint64_t vertices = 0, faces = 0, symbols = 0, splits = 0;
  if (!read_varint(in, at, vertices) || !read_varint(in, at, faces)) {
    return fail("truncated Draco connectivity header");
  }
  if (at >= in.size()) return fail("truncated Draco connectivity header");
  const uint8_t attribute_data = in[at++];
  if (!read_varint(in, at, symbols) || !read_varint(in, at, splits)) {
    return fail("truncated Draco connectivity header");
  }
  if (faces > limits.max_triangles) {
    return fail("declares " + str(faces) + " triangles, limit " + str(limits.max_triangles));
  }
  if (vertices + splits > limits.max_vertices) {
    return fail("declares " + str(vertices + splits) + " vertices, limit " +
                str(limits.max_vertices));
  }
  // One connectivity table per non-position attribute with seams; encode_room writes at most 3.
  if (attribute_data > 3) return fail("declares " + str(attribute_data) + " attribute tables");
  return {};
}

// The attribute descriptors encode_room writes, indexed by unique id (room_codec.hpp).
struct AttributeShape {
  uint8_t type;
  uint8_t data_type;
  uint8_t components;
  const char* name;
};
constexpr std::array<AttributeShape, 4> kLayout = {{
    {draco::GeometryAttribute::POSITION, draco::DT_FLOAT32, 3, "position"},
    {draco::GeometryAttribute::NORMAL, draco::DT_FLOAT32, 3, "normal"},
    {draco::GeometryAttribute::GENERIC, draco::DT_FLOAT32, 2, "channels"},
    {draco::GeometryAttribute::GENERIC, draco::DT_UINT16, 2, "rim"},
}};
static_assert(kPositionId == 0 && kNormalId == 1 && kChannelsId == 2 && kRimId == 3);

// Draco allocates every attribute's values (point count x components x type width, up to 255 x 8
// bytes a value) before it reads them (SequentialAttributeDecoder::DecodePortableAttribute calls
// PointAttribute::Reset first), so a short payload could claim a huge attribute. This reads the
// attribute-decoder block at the position Draco is about to read it from, bitstream 2.2 edgebreaker
// (draco/compression/point_cloud/point_cloud_decoder.cc DecodePointAttributes,
// mesh/mesh_edgebreaker_decoder_impl.cc CreateAttributesDecoder, attributes/attributes_decoder.cc
// and sequential_attribute_decoders_controller.cc DecodeAttributesDecoderData):
//   u8 decoder count; per decoder: i8 attribute-data id, u8 decoder type, u8 traversal method;
//   then per decoder: varint attribute count, per attribute (u8 type, u8 data type,
//   u8 components, u8 normalized, varint unique id), then a u8 sequential decoder type each.
// Only the four descriptors above, each once, pass; every other byte is Draco's to check. Values
// read here are the values Draco reads: a varint that Draco would wrap is never an accepted one.
// Returns the sequential decoder type of each decoder's first attribute, in decoder order, for
// LayoutCheckingDecoder: that attribute's values open the decoder's data.
Result<std::vector<uint8_t>> check_attribute_descriptors(std::span<const uint8_t> in,
                                                         bool normals) {
  // Which of kLayout's attributes the payload holds: all four, or version 2's three.
  const std::array<bool, kLayout.size()> wanted = {true, normals, true, true};
  const size_t expected = normals ? kLayout.size() : kLayout.size() - 1;
  size_t at = 0;
  auto truncated = [] { return fail("truncated attribute descriptors"); };
  if (at >= in.size()) return truncated();
  const size_t decoders = in[at++];
  if (decoders < 1 || decoders > expected) {
    return fail("declares " + str(decoders) + " attribute decoders, expected 1.." + str(expected));
  }
  at += 3 * decoders;
  std::array<bool, kLayout.size()> seen{};
  std::vector<uint8_t> sequential_types;
  size_t total = 0;
  for (size_t d = 0; d < decoders; ++d) {
    uint64_t count = 0;
    if (!read_varint(in, at, count)) return truncated();
    if (count < 1 || count > expected - total) {
      return fail("declares more than " + str(expected) + " attributes, expected " + str(expected));
    }
    for (uint64_t i = 0; i < count; ++i) {
      if (at + 4 > in.size()) return truncated();
      const uint8_t type = in[at], data_type = in[at + 1], components = in[at + 2];
      const uint8_t normalized = in[at + 3];
      at += 4;
      uint64_t id = 0;
      if (!read_varint(in, at, id)) return truncated();
      if (id >= kLayout.size()) continue;  // reported below as the attribute it displaces
      const AttributeShape& want = kLayout[id];
      if (!wanted[id]) {
        return fail(std::string("attribute ") + want.name + " is not part of this layout");
      }
      if (seen[id]) return fail(std::string("attribute ") + want.name + " appears twice");
      if (type != want.type || data_type != want.data_type || components != want.components ||
          normalized != 0) {
        return fail(std::string("attribute ") + want.name +
                    " has the wrong type or component count (" + str(components) +
                    " components of Draco data type " + str(data_type) + ")");
      }
      seen[id] = true;
    }
    if (count == 0 || at + count > in.size()) return truncated();
    sequential_types.push_back(in[at]);  // the first attribute's
    at += count;
    total += count;
  }
  if (total != expected) return fail(str(total) + " attributes, expected " + str(expected));
  for (size_t id = 0; id < kLayout.size(); ++id) {
    if (wanted[id] && !seen[id]) return fail(std::string("missing attribute: ") + kLayout[id].name);
  }
  return sequential_types;
}

// Draco's edgebreaker decoder (what draco::Decoder creates for MESH_EDGEBREAKER_ENCODING) with
// check_attribute_descriptors run on Draco's own buffer between connectivity and attributes, so
// the check reads exactly the bytes Draco reads next, wherever connectivity ended, and nothing of
// an attribute is created or allocated unless the layout is the codec's. Draco still parses every
// byte. This departs from CONTRIBUTING.md ("decode Draco through Draco's decoder") because
// draco::Decoder offers no point between the descriptors and the values; finding the descriptors
// without Draco would mean re-implementing its connectivity decoding (valence context symbols are
// rANS-coded).
//
// It also checks prediction methods before Draco reads them. Draco 1.5.5 (Debian 12's) casts an
// attribute's method byte to its PredictionSchemeMethod enum unchecked
// (SequentialIntegerAttributeDecoder::DecodeValues, and through it the quantization and normal
// decoders); later Draco releases refuse a method outside PREDICTION_NONE..NUM_PREDICTION_SCHEMES
// - 1. The fuzzer found it once Draco was built with UBSan
// (tests/fuzz/seeds/room_decoder_fuzz/prediction_method_*). Only the first attribute of each
// attribute decoder can be checked from here: its values open the decoder's data, while the next
// attribute's start only once Draco has decoded the one before. encode_room puts all four in one
// decoder (one connectivity: room_codec.hpp), so the normal, channel and rim methods stay
// Draco's: an out-of-range value there falls to Draco's delta predictor in a build that does not
// assume enums in range (gcc and clang without -fstrict-enums, Debian's among them), and what it
// decodes then meets this file's value checks. The fuzz build compiles Draco with
// -fno-sanitize=enum for that reason alone (tests/fuzz/run_fuzzers.sh).
class LayoutCheckingDecoder final : public draco::MeshEdgebreakerDecoder {
 public:
  explicit LayoutCheckingDecoder(bool normals) : normals_(normals) {}
  const Status& layout() const { return layout_; }

 protected:
  bool DecodePointAttributes() override {
    const draco::DecoderBuffer* in = buffer();
    auto types = check_attribute_descriptors({reinterpret_cast<const uint8_t*>(in->data_head()),
                                              static_cast<size_t>(in->remaining_size())},
                                             normals_);
    if (!types) {
      layout_ = types.error();
      return false;
    }
    sequential_types_ = std::move(types.value());
    return draco::MeshEdgebreakerDecoder::DecodePointAttributes();
  }

  // PointCloudDecoder::DecodeAllAttributes (one DecodeAttributes a decoder, in order) with the
  // prediction method checked first. A decoder's data starts with its first attribute's values:
  // for every sequential decoder but the generic one (raw values), with the method byte.
  bool DecodeAllAttributes() override {
    if (static_cast<size_t>(num_attributes_decoders()) != sequential_types_.size()) {
      layout_ = fail("attribute decoders differ from their descriptors");
      return false;
    }
    for (int i = 0; i < num_attributes_decoders(); ++i) {
      const draco::DecoderBuffer* in = buffer();
      if (sequential_types_[i] != draco::SEQUENTIAL_ATTRIBUTE_ENCODER_GENERIC &&
          in->remaining_size() > 0) {
        const auto method = static_cast<int8_t>(*in->data_head());
        if (method < draco::PREDICTION_NONE || method >= draco::NUM_PREDICTION_SCHEMES) {
          layout_ = fail("attribute decoder " + std::to_string(i) + ": prediction method " +
                         std::to_string(method) + " is none of Draco's");
          return false;
        }
      }
      // attributes_decoder() hands out a const pointer to what this decoder owns, not const.
      auto* att_decoder = const_cast<draco::AttributesDecoderInterface*>(attributes_decoder(i));
      if (!att_decoder->DecodeAttributes(buffer())) return false;
    }
    return true;
  }

 private:
  bool normals_;
  Status layout_;
  std::vector<uint8_t> sequential_types_;
};

// The attribute with `unique_id`, if its type, width, storage and point mapping are what
// encode_room writes; reading its values afterwards cannot leave its buffer.
Result<const draco::PointAttribute*> find_attribute(const draco::Mesh& m, uint32_t unique_id,
                                                    draco::GeometryAttribute::Type type,
                                                    draco::DataType data_type, int components,
                                                    const char* name) {
  const draco::PointAttribute* att = m.GetAttributeByUniqueId(unique_id);
  if (att == nullptr) return fail(std::string("missing attribute: ") + name);
  if (att->attribute_type() != type || att->data_type() != data_type ||
      att->num_components() != components) {
    return fail(std::string("attribute ") + name + " has the wrong type or component count");
  }
  const size_t stride = static_cast<size_t>(draco::DataTypeLength(data_type)) * components;
  if (att->byte_stride() != static_cast<int64_t>(stride) || att->byte_offset() != 0 ||
      att->buffer() == nullptr || att->buffer()->data_size() < att->size() * stride) {
    return fail(std::string("attribute ") + name + " has an unexpected storage layout");
  }
  if (!att->is_mapping_identity() && att->indices_map_size() < m.num_points()) {
    return fail(std::string("attribute ") + name + " maps fewer points than the mesh has");
  }
  for (uint32_t p = 0; p < m.num_points(); ++p) {
    if (att->mapped_index(draco::PointIndex(p)).value() >= att->size()) {
      return fail(std::string("attribute ") + name + " maps a point to a missing value");
    }
  }
  return att;
}

template <typename T, int N>
std::array<T, N> value(const draco::PointAttribute* att, uint32_t point) {
  std::array<T, N> out;
  std::memcpy(out.data(), att->GetAddressOfMappedIndex(draco::PointIndex(point)), sizeof(out));
  return out;
}

}  // namespace

Result<DecodedRoom> decode_room(std::span<const uint8_t> payload, const DecodeLimits& asked) {
  // The ceilings bound the worst-case allocation the header documents, whatever a caller asks.
  const DecodeLimits limits = {
      std::min(asked.max_bytes, kMaxPayloadBytes), std::min(asked.max_vertices, kMaxVertices),
      std::min(asked.max_triangles, kMaxTriangles), asked.portal_count, asked.normals};
  if (payload.empty()) return fail("empty");
  if (payload.size() > limits.max_bytes) {
    return fail(str(payload.size()) + " bytes, limit " + str(limits.max_bytes));
  }
  if (Status s = check_header(payload, limits); !s) return s.error();

  draco::DecoderBuffer buffer;
  buffer.Init(reinterpret_cast<const char*>(payload.data()), payload.size());
  draco::Mesh m;
  LayoutCheckingDecoder decoder(limits.normals);
  const draco::Status status = decoder.Decode(draco::DecoderOptions(), &buffer, &m);
  if (!decoder.layout()) return decoder.layout().error();
  if (!status.ok()) return fail("Draco: " + status.error_msg_string());

  const uint32_t n = m.num_points();
  const uint32_t t = m.num_faces();
  if (n < 3 || n > limits.max_vertices) {
    return fail(str(n) + " vertices, outside 3.." + str(limits.max_vertices));
  }
  if (t < 1 || t > limits.max_triangles) {
    return fail(str(t) + " triangles, outside 1.." + str(limits.max_triangles));
  }
  const int attributes = limits.normals ? 4 : 3;
  if (m.num_attributes() != attributes) {
    return fail(str(static_cast<size_t>(m.num_attributes())) + " attributes, expected " +
                str(static_cast<size_t>(attributes)));
  }
  using G = draco::GeometryAttribute;
  auto pos = find_attribute(m, kPositionId, G::POSITION, draco::DT_FLOAT32, 3, "position");
  if (!pos) return pos.error();
  Result<const draco::PointAttribute*> nrm = nullptr;
  if (limits.normals) {
    nrm = find_attribute(m, kNormalId, G::NORMAL, draco::DT_FLOAT32, 3, "normal");
    if (!nrm) return nrm.error();
  }
  auto chn = find_attribute(m, kChannelsId, G::GENERIC, draco::DT_FLOAT32, 2, "channels");
  if (!chn) return chn.error();
  auto rim = find_attribute(m, kRimId, G::GENERIC, draco::DT_UINT16, 2, "rim");
  if (!rim) return rim.error();

  DecodedRoom out;
  out.positions.resize(n);
  if (limits.normals) out.normals.resize(n);
  out.roughness.resize(n);
  out.mineral.resize(n);
  out.rim_portal.resize(n);
  out.rim_index.resize(n);
  for (uint32_t v = 0; v < n; ++v) {
    const auto p = value<float, 3>(*pos, v);
    const auto c = value<float, 2>(*chn, v);
    const auto r = value<uint16_t, 2>(*rim, v);
    out.positions[v] = {p[0], p[1], p[2]};
    out.roughness[v] = c[0];
    out.mineral[v] = c[1];
    if (!finite(out.positions[v]) || !within_offset(out.positions[v])) {
      return fail("vertex " + str(v) + ": position not finite or beyond the room's frame");
    }
    if (limits.normals) {
      const auto q = value<float, 3>(*nrm, v);
      out.normals[v] = {q[0], q[1], q[2]};
      if (!finite(out.normals[v]) || !unit(out.normals[v])) {
        return fail("vertex " + str(v) + ": normal is not unit length");
      }
    }
    if (!in_unit_range(c[0]) || !in_unit_range(c[1])) {
      return fail("vertex " + str(v) + ": channel outside [0, 1]");
    }
    if (r[0] > limits.portal_count || r[0] > kMaxPortals) {
      return fail("vertex " + str(v) + ": rim slot " + str(r[0] - 1u) + " out of range");
    }
    if (r[0] == 0 && r[1] != 0) return fail("vertex " + str(v) + ": rim index off any rim");
    // The wire's grid, not this build's world grid: rooms of a server on any power-of-two grid
    // down to 1/256 m decode (grid.hpp).
    if (r[0] > 0 && !on_grid(out.positions[v], grid::kWireStepLog2)) {
      return fail("vertex " + str(v) + ": rim vertex is not on the 1/256 m grid");
    }
    out.rim_portal[v] = static_cast<int8_t>(static_cast<int>(r[0]) - 1);
    out.rim_index[v] = r[1];
  }
  out.indices.resize(size_t{3} * t);
  for (uint32_t f = 0; f < t; ++f) {
    const draco::Mesh::Face& face = m.face(draco::FaceIndex(f));
    for (int k = 0; k < 3; ++k) {
      const uint32_t i = face[k].value();
      if (i >= n) return fail("triangle " + str(f) + ": index out of range");
      out.indices[3 * f + k] = i;
    }
    if (face[0] == face[1] || face[1] == face[2] || face[0] == face[2]) {
      return fail("triangle " + str(f) + " is degenerate");
    }
  }
  return out;
}

Status derive_normals(DecodedRoom& room, Vec3 origin, std::span<const PortalDisc> portals) {
  const size_t n = room.positions.size();
  if (room.rim_portal.size() != n || room.rim_index.size() != n) {
    return fail("per-vertex arrays differ in length");
  }
  auto at = [&](uint32_t v) {
    const float3 p = room.positions[v];
    return Vec3{p.x, p.y, p.z};
  };
  std::vector<Vec3> sum(n);
  for (size_t i = 0; i + 2 < room.indices.size(); i += 3) {
    const uint32_t a = room.indices[i], b = room.indices[i + 1], c = room.indices[i + 2];
    if (a >= n || b >= n || c >= n) return fail("triangle " + str(i / 3) + ": index out of range");
    const Vec3 pa = at(a), u = at(b) - pa, w = at(c) - pa;
    const Vec3 face = {u.y * w.z - u.z * w.y, u.z * w.x - u.x * w.z, u.x * w.y - u.y * w.x};
    sum[a] = sum[a] + face;
    sum[b] = sum[b] + face;
    sum[c] = sum[c] + face;
  }
  room.normals.resize(n);
  for (size_t v = 0; v < n; ++v) {
    Vec3 dir = sum[v];
    if (const int slot = room.rim_portal[v]; slot >= 0) {
      if (static_cast<size_t>(slot) >= portals.size()) {
        return fail("vertex " + str(v) + ": rim slot " + str(static_cast<size_t>(slot)) +
                    " has no portal disc");
      }
      const PortalDisc& disc = portals[slot];
      const Vec3 d = origin + at(static_cast<uint32_t>(v)) - disc.centre;
      const Vec3 radial = d - disc.normal * dot(d, disc.normal);
      if (length_squared(radial) > 0) dir = -radial;
    }
    const double len = length(dir);
    room.normals[v] = len > 0
                          ? float3{static_cast<float>(dir.x / len), static_cast<float>(dir.y / len),
                                   static_cast<float>(dir.z / len)}
                          : float3{0, 1, 0};
  }
  return {};
}

}  // namespace grotto::codec
