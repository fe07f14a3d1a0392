// How much decode_room allocates for hostile payloads. A counting global operator new (it serves
// this whole test binary, Draco's allocations included) records, while one payload decodes, the
// largest single allocation and the peak of bytes allocated and not yet freed.
#include <draco/compression/expert_encode.h>
#include <draco/mesh/mesh.h>
#include <gtest/gtest.h>
#include <malloc.h>

#include <algorithm>
#include <atomic>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <memory>
#include <new>
#include <vector>

#include "common/codec/room_codec.hpp"
#include "common/core/grid.hpp"

namespace {

std::atomic<bool> g_counting{false};
std::atomic<int64_t> g_live{0};
std::atomic<int64_t> g_peak{0};
std::atomic<size_t> g_largest{0};

void* counted_new(size_t n) {
  void* p = std::malloc(n == 0 ? 1 : n);
  if (p == nullptr) throw std::bad_alloc();
  if (g_counting.load(std::memory_order_relaxed)) {
    const int64_t live = g_live += static_cast<int64_t>(malloc_usable_size(p));
    int64_t peak = g_peak.load();
    while (live > peak && !g_peak.compare_exchange_weak(peak, live)) {
    }
    size_t largest = g_largest.load();
    while (n > largest && !g_largest.compare_exchange_weak(largest, n)) {
    }
  }
  return p;
}

void counted_delete(void* p) noexcept {
  if (p == nullptr) return;
  if (g_counting.load(std::memory_order_relaxed)) {
    g_live -= static_cast<int64_t>(malloc_usable_size(p));
  }
  std::free(p);
}

}  // namespace

void* operator new(size_t n) {
  return counted_new(n);
}
void* operator new[](size_t n) {
  return counted_new(n);
}
void operator delete(void* p) noexcept {
  counted_delete(p);
}
void operator delete[](void* p) noexcept {
  counted_delete(p);
}
void operator delete(void* p, size_t) noexcept {
  counted_delete(p);
}
void operator delete[](void* p, size_t) noexcept {
  counted_delete(p);
}

namespace grotto::codec {
namespace {

struct Allocation {
  int64_t peak_bytes = 0;    // most bytes live at once, above what was live before
  size_t largest_bytes = 0;  // the largest single request
};

// Decodes `payload` and reports what the decode allocated. The decoded room (or error) is freed
// inside the measurement.
Allocation measure(const std::vector<uint8_t>& payload, const DecodeLimits& limits,
                   std::string* error) {
  g_live = 0;
  g_peak = 0;
  g_largest = 0;
  g_counting = true;
  {
    auto r = decode_room(payload, limits);
    if (!r.ok()) *error = r.error().message;
  }
  g_counting = false;
  return {g_peak.load(), g_largest.load()};
}

// A g x g grid of vertices 1/4 m apart (on the world grid), two triangles a cell, as a Draco
// mesh whose points are the mesh's corners: every corner is its own point, positions are shared
// through an explicit mapping, and each non-position attribute has one value a corner, so
// Draco's edgebreaker sees a seam on every edge of those attributes and each of them carries
// 3 x triangles values: the most values a payload can make Draco allocate for a triangle count.
struct Grid {
  int g = 0;
  uint32_t vertices() const { return static_cast<uint32_t>(g * g); }
  uint32_t triangles() const { return static_cast<uint32_t>(2 * (g - 1) * (g - 1)); }
  std::array<float, 3> position(int v) const {
    return {0.25f * static_cast<float>(v % g), 0.25f * static_cast<float>(v / g), 1.0f};
  }
  std::vector<std::array<uint32_t, 3>> faces() const {
    std::vector<std::array<uint32_t, 3>> out;
    for (int y = 0; y + 1 < g; ++y) {
      for (int x = 0; x + 1 < g; ++x) {
        const uint32_t a = static_cast<uint32_t>(y * g + x), b = a + 1;
        const uint32_t c = a + static_cast<uint32_t>(g), d = c + 1;
        out.push_back({a, b, d});
        out.push_back({a, d, c});
      }
    }
    return out;
  }
};

std::vector<uint8_t> encode(draco::Mesh& m, const std::vector<std::pair<int, int>>& quantization,
                            int speed = 3) {
  draco::ExpertEncoder encoder(m);
  encoder.SetEncodingMethod(draco::MESH_EDGEBREAKER_ENCODING);
  encoder.SetSpeedOptions(speed, speed);
  for (auto [id, bits] : quantization)
    encoder.SetAttributeQuantization(id, bits);
  draco::EncoderBuffer buffer;
  if (!encoder.EncodeToBuffer(&buffer).ok()) return {};
  return {buffer.data(), buffer.data() + buffer.size()};
}

int add(draco::Mesh& m, std::unique_ptr<draco::PointAttribute> att, uint32_t unique_id) {
  const int id = m.AddAttribute(std::move(att));
  m.attribute(id)->set_unique_id(unique_id);
  return id;
}

// The four attributes of room_codec.hpp with one value per corner (seams everywhere).
std::vector<uint8_t> seamed_grid_payload(const Grid& grid, int speed) {
  using G = draco::GeometryAttribute;
  const auto faces = grid.faces();
  const uint32_t corners = 3 * static_cast<uint32_t>(faces.size());
  draco::Mesh m;
  m.set_num_points(corners);
  auto pos = std::make_unique<draco::PointAttribute>();
  pos->Init(G::POSITION, 3, draco::DT_FLOAT32, false, grid.vertices());
  for (uint32_t v = 0; v < grid.vertices(); ++v) {
    pos->SetAttributeValue(draco::AttributeValueIndex(v),
                           grid.position(static_cast<int>(v)).data());
  }
  pos->SetExplicitMapping(corners);
  auto nrm = std::make_unique<draco::PointAttribute>();
  nrm->Init(G::NORMAL, 3, draco::DT_FLOAT32, false, corners);
  auto chn = std::make_unique<draco::PointAttribute>();
  chn->Init(G::GENERIC, 2, draco::DT_FLOAT32, false, corners);
  auto rim = std::make_unique<draco::PointAttribute>();
  rim->Init(G::GENERIC, 2, draco::DT_UINT16, false, corners);
  for (uint32_t f = 0; f < faces.size(); ++f) {
    for (uint32_t k = 0; k < 3; ++k) {
      const uint32_t c = 3 * f + k;
      pos->SetPointMapEntry(draco::PointIndex(c), draco::AttributeValueIndex(faces[f][k]));
      const draco::AttributeValueIndex i(c);
      const float n[3] = {0.0f, 0.0f, -1.0f};
      const float ch[2] = {0.5f, 0.5f};
      const uint16_t r[2] = {0, 0};
      nrm->SetAttributeValue(i, n);
      chn->SetAttributeValue(i, ch);
      rim->SetAttributeValue(i, r);
    }
    m.AddFace(
        {draco::PointIndex(3 * f), draco::PointIndex(3 * f + 1), draco::PointIndex(3 * f + 2)});
  }
  const int p = add(m, std::move(pos), kPositionId);
  const int n = add(m, std::move(nrm), kNormalId);
  const int c = add(m, std::move(chn), kChannelsId);
  add(m, std::move(rim), kRimId);
  return encode(m, {{p, 8}, {n, 8}, {c, 7}}, speed);
}

// The reviewer's payload: a large mesh whose channels attribute (unique id 2) claims 255 float64
// components, 2,040 bytes a value, cut off early in its values. Before the layout check Draco
// allocated vertices x 2,040 bytes for it and only then found the values missing.
std::vector<uint8_t> wide_attribute_payload(const Grid& grid, size_t keep_bytes) {
  using G = draco::GeometryAttribute;
  constexpr int kWide = 255;
  const auto faces = grid.faces();
  draco::Mesh m;
  m.set_num_points(grid.vertices());
  for (const auto& f : faces) {
    m.AddFace({draco::PointIndex(f[0]), draco::PointIndex(f[1]), draco::PointIndex(f[2])});
  }
  // Added first, so that its values come first after the descriptors.
  auto wide = std::make_unique<draco::PointAttribute>();
  wide->Init(G::GENERIC, static_cast<int8_t>(kWide), draco::DT_FLOAT64, false, grid.vertices());
  std::vector<double> row(kWide);
  for (uint32_t v = 0; v < grid.vertices(); ++v) {
    for (int c = 0; c < kWide; ++c)
      row[c] = 0.001 * (v + c);
    wide->SetAttributeValue(draco::AttributeValueIndex(v), row.data());
  }
  auto pos = std::make_unique<draco::PointAttribute>();
  pos->Init(G::POSITION, 3, draco::DT_FLOAT32, false, grid.vertices());
  auto nrm = std::make_unique<draco::PointAttribute>();
  nrm->Init(G::NORMAL, 3, draco::DT_FLOAT32, false, grid.vertices());
  auto rim = std::make_unique<draco::PointAttribute>();
  rim->Init(G::GENERIC, 2, draco::DT_UINT16, false, grid.vertices());
  for (uint32_t v = 0; v < grid.vertices(); ++v) {
    const draco::AttributeValueIndex i(v);
    const float n[3] = {0.0f, 0.0f, -1.0f};
    const uint16_t r[2] = {0, 0};
    pos->SetAttributeValue(i, grid.position(static_cast<int>(v)).data());
    nrm->SetAttributeValue(i, n);
    rim->SetAttributeValue(i, r);
  }
  add(m, std::move(wide), kChannelsId);
  const int p = add(m, std::move(pos), kPositionId);
  const int n = add(m, std::move(nrm), kNormalId);
  add(m, std::move(rim), kRimId);
  std::vector<uint8_t> bytes = encode(m, {{p, 11}, {n, 8}});
  if (bytes.size() > keep_bytes) bytes.resize(keep_bytes);
  return bytes;
}

TEST(RoomCodecAllocation, a_wide_attribute_is_refused_before_draco_allocates_its_values) {
  const Grid grid{96};  // 9,216 vertices, 18,050 triangles: within the patch limits
  ASSERT_LE(grid.vertices(), kPatchMaxVertices);
  ASSERT_LE(grid.triangles(), kPatchMaxTriangles);
  const auto payload = wide_attribute_payload(grid, 32 * 1024);
  ASSERT_EQ(payload.size(), 32u * 1024) << "the encoder did not write the wide attribute";
  std::string error;
  const Allocation a = measure(payload, {}, &error);
  EXPECT_NE(error.find("attribute channels has the wrong type"), std::string::npos) << error;
  // The values alone would be 9,216 x 2,040 = 18.8 MB in one allocation.
  EXPECT_LT(a.largest_bytes, size_t{1} << 20) << "largest allocation " << a.largest_bytes;
  EXPECT_LT(a.peak_bytes, int64_t{4} << 20) << "peak " << a.peak_bytes;
}

// The worst case room_codec.hpp documents, measured: payloads at the limits whose three
// non-position attributes each carry a value per corner, at every kind of Draco speed setting
// (valence and standard edgebreaker, each prediction scheme Draco picks), since the payload, not
// the codec, chooses how Draco decodes it.
void expect_bounded_at_limits(const Grid& grid, const DecodeLimits& limits, int64_t bound,
                              const char* level) {
  ASSERT_LE(grid.vertices(), limits.max_vertices);
  ASSERT_LE(grid.triangles(), limits.max_triangles);
  for (int speed : {0, 3, 5, 7, 9}) {
    const auto payload = seamed_grid_payload(grid, speed);
    ASSERT_FALSE(payload.empty());
    ASSERT_LE(payload.size(), limits.max_bytes);
    std::string error;
    const Allocation a = measure(payload, limits, &error);
    // Its 3 x triangles points are more vertices than the limit: refused, after Draco decoded
    // everything, which is what this measures. From speed 6 on, Draco's encoder splits the mesh
    // on attribute seams, so those payloads declare 3 x triangles vertices and the header check
    // refuses them before Draco allocates anything.
    EXPECT_TRUE(error.find("vertices, outside") != std::string::npos ||
                (speed >= 6 && error.find("vertices, limit") != std::string::npos))
        << error;
    std::printf("%s limits, speed %d: %u triangles, payload %zu B, peak %lld B, largest %zu B\n",
                level, speed, grid.triangles(), payload.size(),
                static_cast<long long>(a.peak_bytes), a.largest_bytes);
    EXPECT_LE(a.peak_bytes, bound) << "speed " << speed;
  }
}

TEST(RoomCodecAllocation, peak_at_the_patch_limits_is_within_the_documented_bound) {
  expect_bounded_at_limits(Grid{127}, DecodeLimits{}, kPatchDecodePeakBytes, "patch");
}

TEST(RoomCodecAllocation, peak_at_the_format_ceilings_is_within_the_documented_bound) {
  expect_bounded_at_limits(Grid{255}, kDetailLimits, kDetailDecodePeakBytes, "detail");
}

}  // namespace
}  // namespace grotto::codec
