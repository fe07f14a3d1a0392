// The room codec (common/codec): round trips of real patch rooms on the world grid, bit-identical
// rims across rooms encoded alone, and a decoder that turns every malformed payload into an error.
#include <draco/compression/config/compression_shared.h>
#include <draco/compression/mesh/mesh_edgebreaker_decoder.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <iostream>
#include <map>
#include <tuple>

#include "common/codec/room_codec.hpp"
#include "common/core/grid.hpp"
#include "tests/codec/draco_payload.hpp"

namespace grotto::codec {
namespace {

using mesh::RoomMesh;
using mesh::core::float3;

class RoomCodecTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    world_ = new cave::World(cave::World::create(42, cave::LayoutParams{}).value());
    ctx_ = new mesh::MeshContext(mesh::MeshContext::create(*world_, mesh::MeshParams{}).value());
    region_ = new cave::Region(cave::generate_region(*world_, {0, 0, 0}, {0, 0, 0}));
    meshes_ = new std::map<cave::RoomId, RoomMesh>();
    for (const cave::Room& r : region_->rooms) {
      auto m = mesh::build_room_mesh(*ctx_, r, mesh::Lod::kPatch);
      if (m.ok()) meshes_->emplace(r.id, std::move(m).value());
    }
  }
  static void TearDownTestSuite() {
    delete meshes_;
    delete region_;
    delete ctx_;
    delete world_;
  }
  static const RoomMesh& any_room() { return meshes_->begin()->second; }
  static std::vector<uint8_t> encoded(const RoomMesh& m) {
    auto bytes = encode_room(m);
    EXPECT_TRUE(bytes.ok()) << (bytes.ok() ? "" : bytes.error().message);
    return bytes.ok() ? bytes.value() : std::vector<uint8_t>{};
  }

  static cave::World* world_;
  static mesh::MeshContext* ctx_;
  static cave::Region* region_;
  static std::map<cave::RoomId, RoomMesh>* meshes_;
};
cave::World* RoomCodecTest::world_ = nullptr;
mesh::MeshContext* RoomCodecTest::ctx_ = nullptr;
cave::Region* RoomCodecTest::region_ = nullptr;
std::map<cave::RoomId, RoomMesh>* RoomCodecTest::meshes_ = nullptr;

// Grid units of a float offset, as a key: decoded vertices are found again by their snapped
// positions (Draco reorders vertices; two vertices of a patch mesh never share a grid cell: its
// shortest edges are ~0.13 m, the cell 1/64 m).
using GridKey = std::tuple<int64_t, int64_t, int64_t>;
GridKey grid_key(float3 p) {
  auto k = [](float v) { return static_cast<int64_t>(std::llround(v / grid::kStep)); };
  return {k(p.x), k(p.y), k(p.z)};
}

// The original vertex a decoded one came from: in its own grid cell, or a neighbouring one where
// the original lay half a step between two. UINT32_MAX when none.
uint32_t original_of(const std::map<GridKey, uint32_t>& original, float3 decoded) {
  const auto [kx, ky, kz] = grid_key(decoded);
  for (int64_t dx = -1; dx <= 1; ++dx)
    for (int64_t dy = -1; dy <= 1; ++dy)
      for (int64_t dz = -1; dz <= 1; ++dz)
        if (auto it = original.find({kx + dx, ky + dy, kz + dz}); it != original.end())
          return it->second;
  return UINT32_MAX;
}

// A triangle with its smallest index first (orientation kept).
std::array<uint32_t, 3> rotated(uint32_t a, uint32_t b, uint32_t c) {
  if (b < a && b < c) return {b, c, a};
  if (c < a && c < b) return {c, a, b};
  return {a, b, c};
}

std::string message(const Result<DecodedRoom>& r) {
  return r.ok() ? std::string("(decoded)") : r.error().message;
}

// Every invariant decode_room promises, for rooms that decoded from altered bytes.
void expect_valid(const DecodedRoom& r, int portal_count) {
  const size_t n = r.vertex_count();
  ASSERT_EQ(r.normals.size(), n);
  ASSERT_EQ(r.rim_portal.size(), n);
  for (size_t v = 0; v < n; ++v) {
    ASSERT_TRUE(std::isfinite(r.positions[v].x));
    ASSERT_LT(r.rim_portal[v], portal_count);
    ASSERT_GE(r.roughness[v], 0.0f);
    ASSERT_LE(r.mineral[v], 1.0f);
  }
  for (uint32_t i : r.indices)
    ASSERT_LT(i, n);
}

TEST_F(RoomCodecTest, round_trip_keeps_positions_within_half_a_step_and_rims_exact) {
  ASSERT_GT(meshes_->size(), 50u);
  // Default quantization: 8-bit octahedral normals stay within a degree, channels within half
  // a step.
  const float kCosOneDegree = 0.99985f;
  const double channel_tolerance = 0.5 / ((1 << EncodeOptions{}.channel_bits) - 1) + 1e-6;
  size_t rim_vertices = 0;
  for (const auto& [id, m] : *meshes_) {
    SCOPED_TRACE(id.to_string());
    auto decoded = decode_room(encoded(m));
    ASSERT_TRUE(decoded.ok()) << message(decoded);
    const DecodedRoom& d = decoded.value();
    ASSERT_EQ(d.vertex_count(), m.vertex_count());
    ASSERT_EQ(d.triangle_count(), m.triangle_count());

    std::map<GridKey, uint32_t> original;
    for (uint32_t v = 0; v < m.vertex_count(); ++v)
      original.emplace(grid_key(m.positions[v]), v);
    ASSERT_EQ(original.size(), m.vertex_count()) << "two vertices in one grid cell";

    std::vector<uint32_t> to_original(d.vertex_count());
    for (uint32_t v = 0; v < d.vertex_count(); ++v) {
      const uint32_t o = original_of(original, d.positions[v]);
      ASSERT_NE(o, UINT32_MAX) << "decoded vertex " << v << " matches no original vertex";
      to_original[v] = o;
      const float3 a = d.positions[v], b = m.positions[o];
      // Half a step, plus float32's rounding of the offset from the quantization origin, which
      // decides the nearer grid point: 2^-18 m at a hall's 40 m (1e-6 did for 20 m rooms).
      for (float delta : {a.x - b.x, a.y - b.y, a.z - b.z})
        EXPECT_LE(std::fabs(delta), 0.5 * grid::kStep + std::ldexp(1.0, -18));
      EXPECT_TRUE(grid::on_grid(a.x) && grid::on_grid(a.y) && grid::on_grid(a.z));
      EXPECT_EQ(d.rim_portal[v], m.rim_portal[o]);
      if (m.rim_portal[o] >= 0) {
        ++rim_vertices;
        EXPECT_EQ(d.rim_index[v], m.rim_index[o]);
        EXPECT_EQ(std::memcmp(&a, &b, sizeof a), 0) << "rim vertex moved";
      }
      const float3 p = d.normals[v], q = m.normals[o];
      EXPECT_GT(p.x * q.x + p.y * q.y + p.z * q.z, kCosOneDegree);
      EXPECT_NEAR(d.roughness[v], m.roughness[o], channel_tolerance);
      EXPECT_NEAR(d.mineral[v], m.mineral[o], channel_tolerance);
    }
    std::vector<std::array<uint32_t, 3>> want, got;
    for (size_t i = 0; i < m.indices.size(); i += 3)
      want.push_back(rotated(m.indices[i], m.indices[i + 1], m.indices[i + 2]));
    for (size_t i = 0; i < d.indices.size(); i += 3) {
      got.push_back(rotated(to_original[d.indices[i]], to_original[d.indices[i + 1]],
                            to_original[d.indices[i + 2]]));
    }
    std::sort(want.begin(), want.end());
    std::sort(got.begin(), got.end());
    EXPECT_EQ(got, want) << "triangles or their orientation changed";
  }
  EXPECT_GT(rim_vertices, 1000u);
}

// The rim of portal `slot` in a decoded room: world position and normal by loop index.
struct RimVertex {
  Vec3 world;
  float3 normal;
};
std::map<uint16_t, RimVertex> rim_of(const DecodedRoom& d, Vec3 origin, int slot) {
  std::map<uint16_t, RimVertex> rim;
  for (size_t v = 0; v < d.vertex_count(); ++v) {
    if (d.rim_portal[v] != slot) continue;
    const float3 p = d.positions[v];
    rim[d.rim_index[v]] = {origin + Vec3{p.x, p.y, p.z}, d.normals[v]};
  }
  return rim;
}

void expect_error(const Result<DecodedRoom>& r, const std::string& needle);

// Both layouts: version 1's normals as sent, version 2's derived by each room alone.
void expect_bit_identical_rims(const cave::Region& region,
                               const std::map<cave::RoomId, RoomMesh>& meshes, bool normals) {
  std::map<cave::RoomId, DecodedRoom> decoded;
  EncodeOptions options;
  options.normals = normals;
  DecodeLimits limits;
  limits.normals = normals;
  for (const auto& [id, m] : meshes) {
    auto bytes = encode_room(m, options);
    ASSERT_TRUE(bytes.ok());
    auto d = decode_room(bytes.value(), limits);
    ASSERT_TRUE(d.ok()) << message(d);
    if (!normals) {
      std::vector<PortalDisc> discs;
      for (const cave::Portal& p : region.find(id)->portals)
        discs.push_back({p.centre, p.normal});
      ASSERT_TRUE(derive_normals(d.value(), m.origin, discs).ok());
    }
    decoded.emplace(id, std::move(d).value());
  }
  size_t portals = 0;
  for (const cave::Room& a : region.rooms) {
    for (size_t sa = 0; sa < a.portals.size(); ++sa) {
      const cave::RoomId b_id = a.portals[sa].neighbour;
      if (!(a.id < b_id) || !decoded.count(a.id) || !decoded.count(b_id)) continue;
      const cave::Room* b = region.find(b_id);
      ASSERT_NE(b, nullptr);
      int sb = -1;
      for (size_t k = 0; k < b->portals.size(); ++k)
        if (b->portals[k].neighbour == a.id) sb = static_cast<int>(k);
      ASSERT_GE(sb, 0);
      SCOPED_TRACE(a.id.to_string() + " - " + b_id.to_string());
      auto ra = rim_of(decoded.at(a.id), meshes.at(a.id).origin, static_cast<int>(sa));
      auto rb = rim_of(decoded.at(b_id), meshes.at(b_id).origin, sb);
      ASSERT_GE(ra.size(), 3u);
      ASSERT_EQ(ra.size(), rb.size());
      // Loop indices 0..K-1 in both: the same cyclic order.
      EXPECT_EQ(ra.begin()->first, 0);
      EXPECT_EQ(ra.rbegin()->first, ra.size() - 1);
      for (const auto& [k, va] : ra) {
        ASSERT_TRUE(rb.count(k)) << "loop index " << k << " missing in the neighbour";
        const RimVertex& vb = rb.at(k);
        EXPECT_EQ(std::memcmp(&va.world, &vb.world, sizeof(Vec3)), 0) << "position " << k;
        EXPECT_EQ(std::memcmp(&va.normal, &vb.normal, sizeof(float3)), 0) << "normal " << k;
      }
      ++portals;
    }
  }
  EXPECT_GT(portals, 50u);
}

TEST_F(RoomCodecTest, neighbouring_rooms_encoded_alone_decode_bit_identical_rims) {
  expect_bit_identical_rims(*region_, *meshes_, true);
}

TEST_F(RoomCodecTest, version_2_rooms_derive_bit_identical_rim_normals_alone) {
  expect_bit_identical_rims(*region_, *meshes_, false);
}

// Version 2's derived normals against the mesh stage's (computed from unquantized positions; rim
// normals from the canonical loop's angle): close everywhere, and a version 2 payload is smaller.
TEST_F(RoomCodecTest, derived_normals_follow_the_mesh_normals) {
  EncodeOptions without;
  without.normals = false;
  DecodeLimits limits;
  limits.normals = false;
  std::vector<double> angles;
  size_t bytes_v1 = 0, bytes_v2 = 0;
  for (const auto& [id, m] : *meshes_) {
    auto v2 = encode_room(m, without);
    ASSERT_TRUE(v2.ok());
    bytes_v2 += v2->size();
    bytes_v1 += encoded(m).size();
    auto d = decode_room(v2.value(), limits);
    ASSERT_TRUE(d.ok()) << message(d);
    EXPECT_TRUE(d->normals.empty());
    std::vector<PortalDisc> discs;
    for (const cave::Portal& p : region_->find(id)->portals)
      discs.push_back({p.centre, p.normal});
    ASSERT_TRUE(derive_normals(d.value(), m.origin, discs).ok());
    // Find each decoded vertex's mesh vertex by its grid cell (Draco reorders vertices).
    std::map<GridKey, uint32_t> original;
    for (uint32_t v = 0; v < m.vertex_count(); ++v)
      original.emplace(grid_key(m.positions[v]), v);
    for (size_t v = 0; v < d->vertex_count(); ++v) {
      const uint32_t o = original_of(original, d->positions[v]);
      ASSERT_NE(o, UINT32_MAX);
      const float3 a = d->normals[v], b = m.normals[o];
      EXPECT_NEAR(std::sqrt(a.x * a.x + a.y * a.y + a.z * a.z), 1.0, 1e-6);
      const double c =
          std::clamp(double{a.x} * b.x + double{a.y} * b.y + double{a.z} * b.z, -1.0, 1.0);
      angles.push_back(std::acos(c) * 180.0 / 3.14159265358979);
    }
  }
  std::sort(angles.begin(), angles.end());
  const double median = angles[angles.size() / 2], p99 = angles[angles.size() * 99 / 100];
  std::cout << "derived normals vs mesh normals over " << angles.size() << " vertices: median "
            << median << " deg, p99 " << p99 << " deg, max " << angles.back() << " deg; payload "
            << bytes_v2 << " B vs " << bytes_v1 << " B with normals\n";
  // Measured (seed 42, sector 0,0,0): median 0.41, p99 1.47, max 3.2 degrees.
  EXPECT_LT(median, 1.0);
  EXPECT_LT(p99, 3.0);
  EXPECT_LT(angles.back(), 8.0);
  EXPECT_LT(bytes_v2 * 10, bytes_v1 * 9) << "leaving normals out saves over a tenth";
}

TEST_F(RoomCodecTest, a_payload_of_the_other_layout_is_refused) {
  EncodeOptions without;
  without.normals = false;
  auto v2 = encode_room(any_room(), without);
  ASSERT_TRUE(v2.ok());
  expect_error(decode_room(v2.value()), "3 attributes, expected 4");
  DecodeLimits limits;
  limits.normals = false;
  expect_error(decode_room(encoded(any_room()), limits), "attributes, expected 3");
  EXPECT_TRUE(decode_room(v2.value(), limits).ok());
}

TEST_F(RoomCodecTest, derive_normals_refuses_a_rim_slot_without_a_disc) {
  DecodeLimits limits;
  limits.normals = false;
  EncodeOptions without;
  without.normals = false;
  const RoomMesh& m = any_room();
  auto d = decode_room(encode_room(m, without).value(), limits);
  ASSERT_TRUE(d.ok());
  Status s = derive_normals(d.value(), m.origin, {});
  ASSERT_FALSE(s.ok());
  EXPECT_NE(s.error().message.find("has no portal disc"), std::string::npos) << s.error().message;
}

TEST_F(RoomCodecTest, encoding_and_decoding_are_deterministic) {
  const RoomMesh& m = any_room();
  const std::vector<uint8_t> a = encoded(m), b = encoded(m);
  EXPECT_EQ(a, b);
  auto x = decode_room(a), y = decode_room(a);
  ASSERT_TRUE(x.ok() && y.ok());
  auto same = [](const auto& u, const auto& v) {
    return u.size() == v.size() && std::memcmp(u.data(), v.data(), u.size() * sizeof(u[0])) == 0;
  };
  EXPECT_TRUE(same(x->positions, y->positions));
  EXPECT_TRUE(same(x->normals, y->normals));
  EXPECT_TRUE(same(x->roughness, y->roughness));
  EXPECT_TRUE(same(x->mineral, y->mineral));
  EXPECT_TRUE(same(x->rim_portal, y->rim_portal));
  EXPECT_TRUE(same(x->rim_index, y->rim_index));
  EXPECT_TRUE(same(x->indices, y->indices));
}

TEST_F(RoomCodecTest, decoded_rooms_encode_again) {
  for (const auto& [id, m] : *meshes_) {
    auto d = decode_room(encoded(m));
    ASSERT_TRUE(d.ok()) << message(d);
    auto again = encode_room(view_of(d.value(), m.origin));
    ASSERT_TRUE(again.ok()) << again.error().message;
    auto d2 = decode_room(again.value());
    ASSERT_TRUE(d2.ok()) << message(d2);
    EXPECT_EQ(d2->vertex_count(), d->vertex_count());
  }
}

// --- Malformed payloads: each yields its error -------------------------------------------------

void expect_error(const Result<DecodedRoom>& r, const std::string& needle) {
  ASSERT_FALSE(r.ok()) << "decoded, expected an error containing '" << needle << "'";
  EXPECT_EQ(r.error().code, ErrorCode::kInvalidArgument);
  EXPECT_NE(r.error().message.find(needle), std::string::npos) << r.error().message;
}

TEST_F(RoomCodecTest, empty_oversized_and_foreign_payloads_are_errors) {
  expect_error(decode_room({}), "empty");
  std::vector<uint8_t> bytes = encoded(any_room());
  DecodeLimits small;
  small.max_bytes = bytes.size() - 1;
  expect_error(decode_room(bytes, small), "bytes, limit");
  std::vector<uint8_t> huge(kMaxPayloadBytes + 1, 0);
  expect_error(decode_room(huge), "bytes, limit");
  std::vector<uint8_t> text = {'h', 'e', 'l', 'l', 'o', ' ', 'w', 'o', 'r', 'l', 'd', '!'};
  expect_error(decode_room(text), "bad magic");
  std::vector<uint8_t> version = bytes;
  version[6] = 1;
  expect_error(decode_room(version), "bitstream version");
  std::vector<uint8_t> flags = bytes;
  flags[10] = 0x80;
  expect_error(decode_room(flags), "flags");
}

TEST_F(RoomCodecTest, every_truncation_is_an_error) {
  const std::vector<uint8_t> bytes = encoded(any_room());
  ASSERT_TRUE(decode_room(bytes).ok());
  for (size_t len = 0; len < bytes.size(); ++len) {
    auto r = decode_room(std::span(bytes.data(), len));
    EXPECT_FALSE(r.ok()) << "prefix of " << len << " of " << bytes.size() << " bytes decoded";
  }
}

TEST_F(RoomCodecTest, flipped_bytes_are_errors_or_valid_rooms) {
  const RoomMesh& m = any_room();
  const std::vector<uint8_t> bytes = encoded(m);
  const int portals = static_cast<int>(region_->find(m.id)->portals.size());
  DecodeLimits limits;
  limits.portal_count = portals;
  size_t errors = 0;
  for (size_t i = 0; i < bytes.size(); ++i) {
    for (uint8_t mask : {uint8_t{0x01}, uint8_t{0x80}, uint8_t{0xff}}) {
      std::vector<uint8_t> bad = bytes;
      bad[i] ^= mask;
      auto r = decode_room(bad, limits);
      if (!r.ok()) {
        ++errors;
        EXPECT_FALSE(r.error().message.empty());
      } else {
        expect_valid(r.value(), portals);
      }
    }
  }
  EXPECT_GT(errors, bytes.size() / 4);
}

// Rewrites the counts in the connectivity header (after the 11-byte header and the traversal
// type: varint vertices, varint faces) of a valid payload.
std::vector<uint8_t> with_counts(const std::vector<uint8_t>& bytes, uint32_t vertices,
                                 uint32_t faces) {
  size_t at = 12;
  auto skip_varint = [&] {
    while (bytes[at] & 0x80)
      ++at;
    ++at;
  };
  skip_varint();
  skip_varint();
  std::vector<uint8_t> out(bytes.begin(), bytes.begin() + 12);
  for (uint32_t v : {vertices, faces}) {
    while (v >= 0x80) {
      out.push_back(static_cast<uint8_t>(v | 0x80));
      v >>= 7;
    }
    out.push_back(static_cast<uint8_t>(v));
  }
  out.insert(out.end(), bytes.begin() + static_cast<std::ptrdiff_t>(at), bytes.end());
  return out;
}

TEST_F(RoomCodecTest, absurd_declared_counts_are_refused_before_draco_allocates) {
  const RoomMesh& m = any_room();
  const std::vector<uint8_t> bytes = encoded(m);
  const auto nv = static_cast<uint32_t>(m.vertex_count());
  const auto nt = static_cast<uint32_t>(m.triangle_count());
  // The rewrite itself is faithful: the same counts still decode.
  ASSERT_TRUE(decode_room(with_counts(bytes, nv, nt)).ok());
  expect_error(decode_room(with_counts(bytes, nv, 0x7fffffff)), "triangles, limit");
  expect_error(decode_room(with_counts(bytes, 0xffffffff, nt)), "vertices, limit");
  expect_error(decode_room(with_counts(bytes, nv, kMaxTriangles + 1)), "triangles, limit");
  // Counts within the limits but wrong are Draco's to refuse.
  EXPECT_FALSE(decode_room(with_counts(bytes, nv, nt * 4)).ok());
  EXPECT_FALSE(decode_room(with_counts(bytes, nv / 2, nt)).ok());
  // A caller's tighter limits apply too.
  DecodeLimits tight;
  tight.max_vertices = nv - 1;
  expect_error(decode_room(bytes, tight), "vertices");
  tight = {};
  tight.max_triangles = nt - 1;
  expect_error(decode_room(bytes, tight), "triangles, limit");
}

TEST_F(RoomCodecTest, rim_slots_beyond_the_rooms_portals_are_errors) {
  const RoomMesh& m = any_room();
  int highest = -1;
  for (int8_t s : m.rim_portal)
    highest = std::max<int>(highest, s);
  ASSERT_GE(highest, 0);
  DecodeLimits limits;
  limits.portal_count = highest + 1;
  EXPECT_TRUE(decode_room(encoded(m), limits).ok());
  limits.portal_count = highest;
  expect_error(decode_room(encoded(m), limits), "rim slot");
}

using testing::AttributeSpec;
using testing::draco_payload;
using testing::valid_layout;

TEST(RoomCodecLayout, a_hand_built_payload_with_the_right_layout_decodes) {
  auto r = decode_room(draco_payload(valid_layout()));
  ASSERT_TRUE(r.ok()) << r.error().message;
  EXPECT_EQ(r->vertex_count(), 6u);
  EXPECT_EQ(r->triangle_count(), 8u);
}

TEST(RoomCodecLayout, wrong_attribute_layouts_are_errors) {
  using G = draco::GeometryAttribute;
  auto without = [](uint32_t id) {
    auto s = valid_layout();
    s.erase(s.begin() + id);
    return s;
  };
  expect_error(decode_room(draco_payload(without(kNormalId))), "3 attributes, expected 4");
  auto extra = valid_layout();
  extra.push_back({G::GENERIC, draco::DT_FLOAT32, 1, 4, 0, [](int, int) { return 0.0; }});
  // Every non-position attribute brings a connectivity table: refused before Draco reads them.
  expect_error(decode_room(draco_payload(extra)), "declares 4 attribute tables");
  auto renumbered = valid_layout();
  renumbered[1].unique_id = 7;
  expect_error(decode_room(draco_payload(renumbered)), "missing attribute: normal");
  auto flat = valid_layout();
  flat[0].components = 2;
  expect_error(decode_room(draco_payload(flat)), "attribute position has the wrong type");
  auto wide = valid_layout();
  wide[2].components = 3;
  expect_error(decode_room(draco_payload(wide)), "attribute channels has the wrong type");
  auto float_rim = valid_layout();
  float_rim[3].data_type = draco::DT_FLOAT32;
  expect_error(decode_room(draco_payload(float_rim)), "attribute rim has the wrong type");
  auto int_positions = valid_layout();
  int_positions[0].data_type = draco::DT_INT32;
  expect_error(decode_room(draco_payload(int_positions)), "attribute position has the wrong type");
  auto swapped = valid_layout();
  std::swap(swapped[0].unique_id, swapped[1].unique_id);
  expect_error(decode_room(draco_payload(swapped)), "has the wrong type");
  // All four in one attribute decoder (what encode_room writes) and each in its own (what older
  // servers wrote) both decode.
  auto shared = draco_payload(valid_layout(), draco::MESH_EDGEBREAKER_ENCODING, true);
  ASSERT_FALSE(shared.empty());
  EXPECT_TRUE(decode_room(shared).ok());
  auto separate = draco_payload(valid_layout(), draco::MESH_EDGEBREAKER_ENCODING, false);
  ASSERT_FALSE(separate.empty());
  EXPECT_TRUE(decode_room(separate).ok());
}

TEST(RoomCodecLayout, bad_values_are_errors) {
  auto nan = valid_layout();
  nan[0].value = [](int v, int c) {
    return v == 3 ? std::nan("") : testing::octahedron_vertex(v)[c];
  };
  expect_error(decode_room(draco_payload(nan)), "position not finite");
  auto far = valid_layout();
  far[0].value = [](int v, int c) { return testing::octahedron_vertex(v)[c] + 4096.0; };
  expect_error(decode_room(draco_payload(far)), "beyond the room's frame");
  auto long_normal = valid_layout();
  long_normal[1].value = [](int v, int c) { return 1.5 * testing::octahedron_normal(v)[c]; };
  expect_error(decode_room(draco_payload(long_normal)), "normal is not unit");
  auto bright = valid_layout();
  bright[2].value = [](int v, int) { return v == 4 ? 1.5 : 0.5; };
  expect_error(decode_room(draco_payload(bright)), "channel outside [0, 1]");
  auto negative = valid_layout();
  negative[2].value = [](int, int c) { return c == 1 ? -0.25 : 0.5; };
  expect_error(decode_room(draco_payload(negative)), "channel outside [0, 1]");
  auto slot = valid_layout();
  slot[3].value = [](int v, int c) { return v == 0 && c == 0 ? 200.0 : 0.0; };
  expect_error(decode_room(draco_payload(slot)), "rim slot 199 out of range");
  auto stray = valid_layout();
  stray[3].value = [](int v, int c) { return v == 5 && c == 1 ? 9.0 : 0.0; };
  expect_error(decode_room(draco_payload(stray)), "rim index off any rim");
  auto off_grid = valid_layout();
  off_grid[0].value = [](int v, int c) {
    return testing::octahedron_vertex(v)[c] + (v == 0 ? 0.001 : 0.0);
  };
  expect_error(decode_room(draco_payload(off_grid)), "rim vertex is not on the 1/256 m grid");
}

TEST(RoomCodecLayout, other_draco_geometry_is_an_error) {
  auto sequential = draco_payload(valid_layout(), draco::MESH_SEQUENTIAL_ENCODING);
  ASSERT_FALSE(sequential.empty());
  expect_error(decode_room(sequential), "not edgebreaker");
  auto point_cloud = draco_payload(valid_layout());
  point_cloud[7] = draco::POINT_CLOUD;
  expect_error(decode_room(point_cloud), "not a triangle mesh");
}

// Draco's own edgebreaker decoder, noting where each attribute decoder's data starts (the loop
// of PointCloudDecoder::DecodeAllAttributes), so a test can change exactly that byte. A pointer,
// not buffer()->decoded_size(): the edgebreaker decoder re-initializes its buffer mid-stream.
class AttributeDataStarts final : public draco::MeshEdgebreakerDecoder {
 public:
  std::vector<const char*> starts;

 protected:
  bool DecodeAllAttributes() override {
    for (int i = 0; i < num_attributes_decoders(); ++i) {
      starts.push_back(buffer()->data_head());
      auto* att_decoder = const_cast<draco::AttributesDecoderInterface*>(attributes_decoder(i));
      if (!att_decoder->DecodeAttributes(buffer())) return false;
    }
    return true;
  }
};

// The fuzzer, with Draco built with UBSan, found that Draco 1.5.5 casts an attribute's
// prediction-method byte to its enum unchecked (values -86 and 30 in
// tests/fuzz/seeds/room_decoder_fuzz/prediction_method_*). The decoder refuses a method outside
// Draco's before Draco reads it, for the attribute that opens each attribute decoder: with one
// decoder an attribute (Draco's default) all four, with encode_room's one shared decoder the
// position's.
void expect_opening_methods_checked(const std::vector<uint8_t>& payload, size_t decoders) {
  draco::DecoderBuffer buffer;
  buffer.Init(reinterpret_cast<const char*>(payload.data()), payload.size());
  draco::Mesh m;
  AttributeDataStarts data;
  ASSERT_TRUE(data.Decode(draco::DecoderOptions(), &buffer, &m).ok());
  ASSERT_EQ(data.starts.size(), decoders);
  for (size_t i = 0; i < data.starts.size(); ++i) {
    const auto at =
        static_cast<size_t>(data.starts[i] - reinterpret_cast<const char*>(payload.data()));
    ASSERT_LT(at, payload.size());
    // What encode_room wrote there is a method Draco knows (so this is the method byte).
    const auto written = static_cast<int8_t>(payload[at]);
    ASSERT_GE(written, draco::PREDICTION_NONE) << "attribute decoder " << i;
    ASSERT_LT(written, draco::NUM_PREDICTION_SCHEMES) << "attribute decoder " << i;
    for (int method : {-86, 30, static_cast<int>(draco::NUM_PREDICTION_SCHEMES), -3}) {
      auto bad = payload;
      bad[at] = static_cast<uint8_t>(method);
      expect_error(decode_room(bad), "attribute decoder " + std::to_string(i) +
                                         ": prediction method " + std::to_string(method) +
                                         " is none of Draco's");
    }
  }
}

TEST_F(RoomCodecTest, prediction_methods_draco_lacks_are_refused_before_draco_reads_them) {
  expect_opening_methods_checked(encoded(any_room()), 1);
}

// --- The encoder's own contracts ------------------------------------------------------------

TEST_F(RoomCodecTest, encoder_refuses_rooms_that_break_the_contract) {
  auto expect_refused = [](const RoomMesh& m, const std::string& needle) {
    auto r = encode_room(m);
    ASSERT_FALSE(r.ok()) << "encoded, expected '" << needle << "'";
    EXPECT_NE(r.error().message.find(needle), std::string::npos) << r.error().message;
  };
  RoomMesh m = any_room();
  ASSERT_TRUE(encode_room(m).ok());
  RoomMesh bad = m;
  bad.indices[4] = static_cast<uint32_t>(m.vertex_count());
  expect_refused(bad, "index out of range");
  bad = m;
  bad.indices[1] = bad.indices[0];
  expect_refused(bad, "degenerate");
  bad = m;
  bad.origin.x += 0.001;
  expect_refused(bad, "origin is not on the encoder's grid");
  bad = m;
  bad.positions[2].y = std::nanf("");
  expect_refused(bad, "position not finite");
  bad = m;
  bad.normals[1] = {0, 0, 0};
  expect_refused(bad, "normal is not unit");
  bad = m;
  bad.roughness[0] = 2.0f;
  expect_refused(bad, "channel outside");
  bad = m;
  bad.mineral.pop_back();
  expect_refused(bad, "differ in length");
  bad = m;
  for (size_t v = 0; v < bad.vertex_count(); ++v) {
    if (bad.rim_portal[v] >= 0) {
      bad.positions[v].x += 0.001f;
      break;
    }
  }
  expect_refused(bad, "rim vertex is not on the encoder's grid");
  bad = m;
  bad.rim_portal[0] = kMaxPortals;  // would not decode: slots stay below kMaxPortals
  expect_refused(bad, "rim slot 127 out of range");
  EncodeOptions sequential;
  sequential.speed = 10;
  EXPECT_FALSE(encode_room(m, sequential).ok());
  EncodeOptions finer_than_the_wire;
  finer_than_the_wire.grid_step_log2 = grid::kWireStepLog2 + 1;
  EXPECT_FALSE(encode_room(m, finer_than_the_wire).ok());
}

// The wire promises rims on the 1/256 m grid (proto/PROTOCOL.md), which this build's world grid
// lies on: a room from a server that quantizes on 1/256 m (as Grotto did before the 1/64 m grid)
// still decodes, its rims exact, and encodes again at that grid; the world grid refuses it.
TEST_F(RoomCodecTest, rooms_on_the_finer_wire_grid_decode_and_encode_again_at_it) {
  static_assert(grid::kStepLog2 < grid::kWireStepLog2, "the test needs a coarser world grid");
  RoomMesh m = any_room();
  size_t moved = m.vertex_count();
  for (size_t v = 0; v < m.vertex_count() && moved == m.vertex_count(); ++v) {
    if (m.rim_portal[v] >= 0) moved = v;
  }
  ASSERT_LT(moved, m.vertex_count());
  m.positions[moved].x += static_cast<float>(grid::kWireStep);  // exact: a wire-grid offset
  ASSERT_FALSE(grid::on_grid(m.positions[moved].x));
  EXPECT_FALSE(encode_room(m).ok()) << "off the world grid, the default encoder must refuse";
  EncodeOptions wire;
  wire.grid_step_log2 = grid::kWireStepLog2;
  auto bytes = encode_room(m, wire);
  ASSERT_TRUE(bytes.ok()) << bytes.error().message;
  auto decoded = decode_room(bytes.value());
  ASSERT_TRUE(decoded.ok()) << message(decoded);
  const DecodedRoom& d = decoded.value();
  bool found = false;
  for (size_t v = 0; v < d.vertex_count(); ++v) {
    if (d.rim_portal[v] == m.rim_portal[moved] && d.rim_index[v] == m.rim_index[moved]) {
      found = true;
      EXPECT_EQ(std::memcmp(&d.positions[v], &m.positions[moved], sizeof(float3)), 0);
    }
  }
  EXPECT_TRUE(found);
  EXPECT_TRUE(encode_room(view_of(d, m.origin), wire).ok());
  EXPECT_FALSE(encode_room(view_of(d, m.origin)).ok());
}

}  // namespace
}  // namespace grotto::codec
