// The room codec's Draco levers one at a time, on the rooms codec_bench measures: a copy of
// encode_room's Draco set-up with switches (grid step, attributes present, one connectivity,
// edgebreaker coder, prediction schemes, quantization, separate encoding and decoding speeds),
// timed encode and draco::Decoder decode, so that every lever and the old defaults (1/256 m grid,
// 7-bit channels) are compared within one run. Measuring only: the codec is common/codec, and
// nothing here is validated as encode_room validates. Usage: codec_levers --help.
// Results: docs/BENCHMARKS.md ("Room codec").
#include <draco/compression/decode.h>
#include <draco/compression/expert_encode.h>
#include <draco/mesh/mesh.h>

#include <cmath>
#include <cstdio>
#include <string>

#include "bench/flags.hpp"
#include "bench/timing.hpp"
#include "common/codec/room_codec.hpp"
#include "common/mesh/room_mesh.hpp"

using namespace grotto;
using bench::median;
using bench::median_ms;

struct Config {
  std::string name;
  int step_log2 = 8;
  bool nrm = true, chn = true, rim = true;
  int speed = 3;
  int decoding_speed = -1;  // -1: the same as speed
  int split = -1;           // split_mesh_on_seams
  int eb_method = -1;       // edgebreaker_method
  int pos_pred = -1, nrm_pred = -1, chn_pred = -1, rim_pred = -1;
  int normal_bits = 8, channel_bits = 7;
  bool vertex_elements = false;
  // > 0: off rims, send the normal Draco's geometric predictor will predict (area-weighted over the
  // quantized positions, canonicalized as Draco does) when it is this close to the mesh's normal,
  // so that its residual is zero.
  double snap_normal_degrees = 0;
};

std::string exact_text(float v) {
  char t[40];
  std::snprintf(t, sizeof t, "%.17g", static_cast<double>(v));
  return t;
}

std::vector<char> encode(const mesh::RoomMesh& m, const Config& c) {
  const size_t n = m.positions.size();
  draco::Mesh dm;
  dm.set_num_points(n);
  for (size_t i = 0; i < m.indices.size(); i += 3)
    dm.AddFace({draco::PointIndex(m.indices[i]), draco::PointIndex(m.indices[i + 1]),
                draco::PointIndex(m.indices[i + 2])});
  auto mk = [&](draco::GeometryAttribute::Type t, int k, draco::DataType dt) {
    auto a = std::make_unique<draco::PointAttribute>();
    a->Init(t, k, dt, false, n);
    return a;
  };
  auto pos = mk(draco::GeometryAttribute::POSITION, 3, draco::DT_FLOAT32);
  auto nrm = mk(draco::GeometryAttribute::NORMAL, 3, draco::DT_FLOAT32);
  auto chn = mk(draco::GeometryAttribute::GENERIC, 2, draco::DT_FLOAT32);
  auto rim = mk(draco::GeometryAttribute::GENERIC, 2, draco::DT_UINT16);
  double lo[3] = {1e9, 1e9, 1e9}, hi[3] = {-1e9, -1e9, -1e9};
  std::vector<mesh::core::float3> normals = m.normals;
  if (c.snap_normal_degrees > 0) {
    const double step = 1.0 / (1 << c.step_log2);
    float org[3] = {1e9f, 1e9f, 1e9f};
    for (const auto& p : m.positions) {
      org[0] = std::min(org[0], p.x);
      org[1] = std::min(org[1], p.y);
      org[2] = std::min(org[2], p.z);
    }
    for (float& o : org)
      o = static_cast<float>(std::floor(o / step) * step);
    const float inv = static_cast<float>(1.0 / step);
    std::vector<int64_t> q(3 * n);
    for (size_t v = 0; v < n; ++v) {
      const float pv[3] = {m.positions[v].x, m.positions[v].y, m.positions[v].z};
      for (int k = 0; k < 3; ++k)
        q[3 * v + k] = static_cast<int64_t>(std::floor((pv[k] - org[k]) * inv + 0.5f));
    }
    std::vector<int64_t> acc(3 * n, 0);
    for (size_t t = 0; t < m.indices.size(); t += 3) {
      for (int k = 0; k < 3; ++k) {
        const uint32_t a = m.indices[t + k], b = m.indices[t + (k + 1) % 3],
                       cc = m.indices[t + (k + 2) % 3];
        int64_t u[3], w[3];
        for (int j = 0; j < 3; ++j) {
          u[j] = q[3 * b + j] - q[3 * a + j];
          w[j] = q[3 * cc + j] - q[3 * a + j];
        }
        acc[3 * a] += u[1] * w[2] - u[2] * w[1];
        acc[3 * a + 1] += u[2] * w[0] - u[0] * w[2];
        acc[3 * a + 2] += u[0] * w[1] - u[1] * w[0];
      }
    }
    const int64_t center = ((1 << c.normal_bits) - 2) / 2;
    const double cos_tol = std::cos(c.snap_normal_degrees * 3.14159265358979 / 180.0);
    for (size_t v = 0; v < n; ++v) {
      if (m.rim_portal[v] >= 0) continue;
      const int64_t* a = &acc[3 * v];
      const int64_t abs_sum = std::llabs(a[0]) + std::llabs(a[1]) + std::llabs(a[2]);
      if (abs_sum == 0) continue;
      int64_t c0 = a[0] * center / abs_sum, c1 = a[1] * center / abs_sum;
      int64_t c2 = center - std::llabs(c0) - std::llabs(c1);
      if (a[2] < 0) c2 = -c2;
      const double len = std::sqrt(double(c0 * c0 + c1 * c1 + c2 * c2));
      const mesh::core::float3 cand = {float(c0 / len), float(c1 / len), float(c2 / len)};
      const auto& o = m.normals[v];
      if (cand.x * o.x + cand.y * o.y + cand.z * o.z >= cos_tol) normals[v] = cand;
    }
  }
  for (size_t v = 0; v < n; ++v) {
    draco::AttributeValueIndex i(v);
    auto p = m.positions[v];
    auto q = normals[v];
    float pv[3] = {p.x, p.y, p.z}, nv[3] = {q.x, q.y, q.z}, cv[2] = {m.roughness[v], m.mineral[v]};
    uint16_t rv[2] = {uint16_t(m.rim_portal[v] + 1),
                      uint16_t(m.rim_portal[v] >= 0 ? m.rim_index[v] : 0)};
    pos->SetAttributeValue(i, pv);
    nrm->SetAttributeValue(i, nv);
    chn->SetAttributeValue(i, cv);
    rim->SetAttributeValue(i, rv);
    for (int k = 0; k < 3; ++k) {
      lo[k] = std::min(lo[k], (double)pv[k]);
      hi[k] = std::max(hi[k], (double)pv[k]);
    }
  }
  int pos_id = dm.AddAttribute(std::move(pos));
  int nrm_id = c.nrm ? dm.AddAttribute(std::move(nrm)) : -1;
  int chn_id = c.chn ? dm.AddAttribute(std::move(chn)) : -1;
  int rim_id = c.rim ? dm.AddAttribute(std::move(rim)) : -1;
  if (c.vertex_elements)
    for (int a = 0; a < dm.num_attributes(); ++a)
      dm.SetAttributeElementType(a, draco::MESH_VERTEX_ATTRIBUTE);
  const double step = 1.0 / (1 << c.step_log2);
  float origin[3];
  double extent = 0;
  for (int k = 0; k < 3; ++k) {
    origin[k] = std::floor(lo[k] / step) * step;
    extent = std::max(extent, hi[k] - origin[k]);
  }
  int bits = 1;
  while (((1u << bits) - 1) * step < extent)
    ++bits;
  float range = ((1u << bits) - 1) * step;
  draco::ExpertEncoder enc(dm);
  enc.SetEncodingMethod(draco::MESH_EDGEBREAKER_ENCODING);
  enc.SetSpeedOptions(c.speed, c.decoding_speed < 0 ? c.speed : c.decoding_speed);
  if (c.split >= 0) enc.options().SetGlobalBool("split_mesh_on_seams", c.split == 1);
  if (c.eb_method >= 0) enc.options().SetGlobalInt("edgebreaker_method", c.eb_method);
  enc.SetAttributeExplicitQuantization(pos_id, bits, 3, origin, range);
  draco::Options exact = *enc.options().FindAttributeOptions(pos_id);
  exact.SetString("quantization_origin", exact_text(origin[0]) + " " + exact_text(origin[1]) + " " +
                                             exact_text(origin[2]));
  exact.SetString("quantization_range", exact_text(range));
  enc.options().SetAttributeOptions(pos_id, exact);
  if (c.pos_pred >= 0) enc.SetAttributePredictionScheme(pos_id, c.pos_pred);
  if (nrm_id >= 0) {
    enc.SetAttributeQuantization(nrm_id, c.normal_bits);
    if (c.nrm_pred >= 0) enc.SetAttributePredictionScheme(nrm_id, c.nrm_pred);
  }
  const float co[2] = {0, 0};
  if (chn_id >= 0) {
    enc.SetAttributeExplicitQuantization(chn_id, c.channel_bits, 2, co, 1.0f);
    if (c.chn_pred >= 0) enc.SetAttributePredictionScheme(chn_id, c.chn_pred);
  }
  if (rim_id >= 0 && c.rim_pred >= -2 && c.rim_pred != -1)
    enc.SetAttributePredictionScheme(rim_id, c.rim_pred);
  draco::EncoderBuffer buf;
  if (!enc.EncodeToBuffer(&buf).ok()) std::abort();
  return std::vector<char>(buf.data(), buf.data() + buf.size());
}

int main(int argc, char** argv) {
  CLI::App app{
      "codec_levers: each Draco lever of the room codec alone, on the first 100 patch rooms "
      "of a world's sector 0,0,0 (a table on stdout; docs/BENCHMARKS.md, \"Room codec\")"};
  int reps = 3;
  std::uint64_t seed = 7;
  app.add_option("--repetitions", reps, "Timed runs of each lever (the median is reported)")
      ->check(CLI::Range(1, 1000));
  app.add_option("--seed", seed, "World seed (BENCHMARKS' figures: 42)");
  if (auto rc = bench::parse_flags(app, argc, argv)) return *rc;
  cave::World world = cave::World::create(seed, cave::LayoutParams{}).value();
  mesh::MeshContext ctx = mesh::MeshContext::create(world, mesh::MeshParams{}).value();
  cave::Region region = cave::generate_region(world, {0, 0, 0}, {0, 0, 0});
  std::vector<mesh::RoomMesh> patch;
  for (const cave::Room& r : region.rooms) {
    if (patch.size() == 100) break;
    auto p = mesh::build_room_mesh(ctx, r, mesh::Lod::kPatch);
    if (p) patch.push_back(std::move(p).value());
  }
  {
    std::vector<double> edge, minedge, mind;
    for (const auto& m : patch) {
      double mn = 1e9;
      for (size_t i = 0; i < m.indices.size(); i += 3)
        for (int k = 0; k < 3; ++k) {
          auto a = m.positions[m.indices[i + k]], b = m.positions[m.indices[i + (k + 1) % 3]];
          double l = std::sqrt((a.x - b.x) * (a.x - b.x) + (a.y - b.y) * (a.y - b.y) +
                               (a.z - b.z) * (a.z - b.z));
          edge.push_back(l);
          mn = std::min(mn, l);
        }
      minedge.push_back(mn);
    }
    std::sort(minedge.begin(), minedge.end());
    std::printf(
        "edge median %.3f m, p1 %.4f, p5 %.4f; per-room min edge: median %.4f, min %.5f\n",
        median(edge),
        [&] {
          auto e = edge;
          std::sort(e.begin(), e.end());
          return e[e.size() / 100];
        }(),
        [&] {
          auto e = edge;
          std::sort(e.begin(), e.end());
          return e[e.size() / 20];
        }(),
        median(minedge), minedge[0]);
  }
  std::vector<Config> cs;
  auto add = [&](Config c) { cs.push_back(c); };
  Config old{
      "the old defaults: 1/256 m grid, seam tables, Draco's edgebreaker choice, 7-bit channels"};
  old.channel_bits = 7;
  add(old);
  Config c = old;
  c.split = 1;
  c.name = "+ one connectivity (split_mesh_on_seams)";
  add(c);
  c.eb_method = 2;
  c.name = "+ valence edgebreaker at every size";
  add(c);
  c.channel_bits = 6;
  c.name = "+ 6-bit channels";
  add(c);
  c.step_log2 = 7;
  c.name = "+ 1/128 m grid";
  add(c);
  c.step_log2 = 6;
  c.name = "+ 1/64 m grid (the new defaults)";
  add(c);
  const Config now = c;
  auto variant = [&](const std::string& name, auto&& change) {
    Config v = now;
    v.name = name;
    change(v);
    add(v);
  };
  variant("new, 1/32 m grid", [](Config& v) { v.step_log2 = 5; });
  for (int s : {8, 7, 6, 5}) {
    variant("new, positions + connectivity only, 1/" + std::to_string(1 << s) + " m grid",
            [&](Config& v) {
              v.nrm = v.chn = v.rim = false;
              v.step_log2 = s;
            });
  }
  variant("new, positions + connectivity only, Draco's edgebreaker choice", [](Config& v) {
    v.nrm = v.chn = v.rim = false;
    v.eb_method = -1;
  });
  variant("new, positions by constrained multi-parallelogram",
          [](Config& v) { v.pos_pred = draco::MESH_PREDICTION_CONSTRAINED_MULTI_PARALLELOGRAM; });
  variant("new, without normals", [](Config& v) { v.nrm = false; });
  variant("new, without channels", [](Config& v) { v.chn = false; });
  variant("new, without the rim attribute", [](Config& v) { v.rim = false; });
  variant("new, normals by difference",
          [](Config& v) { v.nrm_pred = draco::PREDICTION_DIFFERENCE; });
  variant("new, rim attribute by difference",
          [](Config& v) { v.rim_pred = draco::PREDICTION_DIFFERENCE; });
  variant("new, 7-bit normals", [](Config& v) { v.normal_bits = 7; });
  variant("new, 5-bit channels", [](Config& v) { v.channel_bits = 5; });
  variant("new, speed 0", [](Config& v) { v.speed = 0; });
  variant("new, normals off rims snapped to Draco's prediction within 1 degree",
          [](Config& v) { v.snap_normal_degrees = 1.0; });
  variant("new, normals off rims snapped to Draco's prediction, always",
          [](Config& v) { v.snap_normal_degrees = 180.0; });
  variant("new, speed 5", [](Config& v) {
    v.speed = 5;
    v.eb_method = -1;
  });
  variant("new, encoding speed 3, decoding speed 9", [](Config& v) { v.decoding_speed = 9; });
  std::printf(
      "| lever | bytes/room (median / mean) | payload bits/vertex (median) | encode ms/room "
      "(median / "
      "mean) | decode ms/room (median / mean / max) |\n| --- | ---: | ---: | ---: | ---: |\n");
  for (const Config& lever : cs) {
    std::vector<double> b, bpv, e, d;
    for (const auto& m : patch) {
      std::vector<char> out;
      e.push_back(median_ms(reps, [&] { out = encode(m, lever); }));
      b.push_back(out.size());
      bpv.push_back(8.0 * out.size() / m.vertex_count());
      d.push_back(median_ms(reps, [&] {
        draco::DecoderBuffer buf;
        buf.Init(out.data(), out.size());
        draco::Decoder dec;
        if (!dec.DecodeMeshFromBuffer(&buf).ok()) std::abort();
      }));
    }
    double mean = 0;
    for (double x : b)
      mean += x / b.size();
    double enc_mean = 0, dec_mean = 0;
    for (double x : e)
      enc_mean += x / e.size();
    for (double x : d)
      dec_mean += x / d.size();
    std::printf("| %s | %.0f / %.0f | %.1f | %.3f / %.3f | %.3f / %.3f / %.3f |\n",
                lever.name.c_str(), median(b), mean, median(bpv), median(e), enc_mean, median(d),
                dec_mean, *std::max_element(d.begin(), d.end()));
  }
}
