// Hand-built Draco payloads for the decoder's malformed-layout tests: a small closed mesh (an
// octahedron on the grid) with whatever attributes a test asks for, encoded with Draco's own
// encoder, so each test changes exactly one thing about a payload that is otherwise valid.
#pragma once

#include <draco/compression/expert_encode.h>
#include <draco/mesh/mesh.h>

#include <array>
#include <cstdint>
#include <cstring>
#include <functional>
#include <memory>
#include <vector>

namespace grotto::codec::testing {

struct AttributeSpec {
  draco::GeometryAttribute::Type type = draco::GeometryAttribute::GENERIC;
  draco::DataType data_type = draco::DT_FLOAT32;
  int components = 3;
  uint32_t unique_id = 0;
  int quantization_bits = 0;  // 0: lossless
  // The value of component c of vertex v.
  std::function<double(int v, int c)> value;
};

inline constexpr int kOctahedronVertices = 6;
// Vertex v of an octahedron of radius 1 m centred at (2, 2, 2) m: on the grid.
inline std::array<double, 3> octahedron_vertex(int v) {
  std::array<double, 3> p = {2.0, 2.0, 2.0};
  p[v / 2] += (v % 2 == 0) ? 1.0 : -1.0;
  return p;
}
inline std::array<double, 3> octahedron_normal(int v) {
  std::array<double, 3> n = {0, 0, 0};
  n[v / 2] = (v % 2 == 0) ? -1.0 : 1.0;  // facing the inside, like a room
  return n;
}

// The four attributes as encode_room lays them out (lossless), for tests to edit.
inline std::vector<AttributeSpec> valid_layout() {
  using G = draco::GeometryAttribute;
  return {
      {G::POSITION, draco::DT_FLOAT32, 3, 0, 0,
       [](int v, int c) { return octahedron_vertex(v)[c]; }},
      {G::NORMAL, draco::DT_FLOAT32, 3, 1, 0, [](int v, int c) { return octahedron_normal(v)[c]; }},
      {G::GENERIC, draco::DT_FLOAT32, 2, 2, 0, [](int v, int c) { return 0.1 * (v + c); }},
      // Vertices 0 and 1 on the rim of portal 0, at loop positions 0 and 1.
      {G::GENERIC, draco::DT_UINT16, 2, 3, 0,
       [](int v, int c) { return v < 2 ? (c == 0 ? 1.0 : v) : 0.0; }},
  };
}

// single_connectivity: Draco's "split_mesh_on_seams", every attribute in one attribute decoder.
inline std::vector<uint8_t> draco_payload(const std::vector<AttributeSpec>& specs,
                                          int method = draco::MESH_EDGEBREAKER_ENCODING,
                                          bool single_connectivity = false) {
  draco::Mesh m;
  m.set_num_points(kOctahedronVertices);
  // Faces of the octahedron (+x=0, -x=1, +y=2, -y=3, +z=4, -z=5).
  const int faces[8][3] = {{0, 2, 4}, {2, 1, 4}, {1, 3, 4}, {3, 0, 4},
                           {2, 0, 5}, {1, 2, 5}, {3, 1, 5}, {0, 3, 5}};
  for (const auto& f : faces) {
    m.AddFace({draco::PointIndex(f[0]), draco::PointIndex(f[1]), draco::PointIndex(f[2])});
  }
  std::vector<int> ids;
  for (const AttributeSpec& s : specs) {
    auto att = std::make_unique<draco::PointAttribute>();
    att->Init(s.type, static_cast<int8_t>(s.components), s.data_type, false, kOctahedronVertices);
    for (int v = 0; v < kOctahedronVertices; ++v) {
      std::array<uint8_t, 64> bytes{};
      for (int c = 0; c < s.components; ++c) {
        const double x = s.value(v, c);
        if (s.data_type == draco::DT_FLOAT32) {
          float f = static_cast<float>(x);
          std::memcpy(bytes.data() + 4 * c, &f, 4);
        } else if (s.data_type == draco::DT_UINT16) {
          uint16_t u = static_cast<uint16_t>(x);
          std::memcpy(bytes.data() + 2 * c, &u, 2);
        } else if (s.data_type == draco::DT_INT32) {
          int32_t i = static_cast<int32_t>(x);
          std::memcpy(bytes.data() + 4 * c, &i, 4);
        }
      }
      att->SetAttributeValue(draco::AttributeValueIndex(v), bytes.data());
    }
    const int id = m.AddAttribute(std::move(att));
    m.attribute(id)->set_unique_id(s.unique_id);
    ids.push_back(id);
  }
  draco::ExpertEncoder encoder(m);
  encoder.SetEncodingMethod(method);
  if (single_connectivity) encoder.options().SetGlobalBool("split_mesh_on_seams", true);
  for (size_t i = 0; i < specs.size(); ++i) {
    if (specs[i].quantization_bits > 0) {
      encoder.SetAttributeQuantization(ids[i], specs[i].quantization_bits);
    }
  }
  draco::EncoderBuffer buffer;
  if (!encoder.EncodeToBuffer(&buffer).ok()) return {};
  return {buffer.data(), buffer.data() + buffer.size()};
}

}  // namespace grotto::codec::testing
