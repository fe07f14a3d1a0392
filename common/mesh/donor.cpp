#include "common/mesh/donor.hpp"

#include <algorithm>
#include <array>
#include <cmath>
#include <map>
#include <mutex>
#include <tuple>

namespace grotto::mesh {
namespace {

// Icosahedron: 12 corners, 20 faces counter-clockwise from outside.
constexpr double kT = 1.6180339887498948482;
constexpr double kCorners[12][3] = {{-1, kT, 0}, {1, kT, 0}, {-1, -kT, 0}, {1, -kT, 0},
                                    {0, -1, kT}, {0, 1, kT}, {0, -1, -kT}, {0, 1, -kT},
                                    {kT, 0, -1}, {kT, 0, 1}, {-kT, 0, -1}, {-kT, 0, 1}};
constexpr int kFaces[20][3] = {{0, 11, 5}, {0, 5, 1},  {0, 1, 7},   {0, 7, 10}, {0, 10, 11},
                               {1, 5, 9},  {5, 11, 4}, {11, 10, 2}, {10, 7, 6}, {7, 1, 8},
                               {3, 9, 4},  {3, 4, 2},  {3, 2, 6},   {3, 6, 8},  {3, 8, 9},
                               {4, 9, 5},  {2, 4, 11}, {6, 2, 10},  {8, 6, 7},  {9, 8, 1}};

// Average edge of a frequency-n geodesic sphere of unit radius is about this over n.
constexpr double kEdgeFactor = 1.1;

std::shared_ptr<const DonorSphere> build(int n) {
  auto d = std::make_shared<DonorSphere>();
  d->frequency = n;
  // A lattice point of a face is named by the corners it mixes, so points on shared edges and
  // corners get one vertex: key = sorted (corner, weight) pairs.
  std::map<std::tuple<int, int, int, int, int, int>, uint32_t> index_of;
  auto vertex = [&](const int c[3], const int w[3]) {
    std::array<std::pair<int, int>, 3> parts{{{c[0], w[0]}, {c[1], w[1]}, {c[2], w[2]}}};
    for (auto& p : parts) {
      if (p.second == 0) p.first = -1;
    }
    std::sort(parts.begin(), parts.end());
    auto key = std::make_tuple(parts[0].first, parts[0].second, parts[1].first, parts[1].second,
                               parts[2].first, parts[2].second);
    auto [it, fresh] = index_of.emplace(key, static_cast<uint32_t>(d->directions.size()));
    if (fresh) {
      double p[3] = {0, 0, 0};
      for (int k = 0; k < 3; ++k) {
        for (int a = 0; a < 3; ++a)
          p[a] += kCorners[c[k]][a] * w[k];
      }
      double len = std::sqrt(p[0] * p[0] + p[1] * p[1] + p[2] * p[2]);
      d->directions.push_back({static_cast<float>(p[0] / len), static_cast<float>(p[1] / len),
                               static_cast<float>(p[2] / len)});
    }
    return it->second;
  };
  for (const auto& f : kFaces) {
    // Point (i, j) of the face: weights (n - i - j, i, j) on corners (f0, f1, f2).
    auto at = [&](int i, int j) {
      int w[3] = {n - i - j, i, j};
      return vertex(f, w);
    };
    for (int j = 0; j < n; ++j) {
      for (int i = 0; i + j < n; ++i) {
        uint32_t a = at(i, j), b = at(i + 1, j), c = at(i, j + 1);
        d->indices.insert(d->indices.end(), {a, b, c});
        if (i + j + 1 < n) {
          uint32_t e = at(i + 1, j + 1);
          d->indices.insert(d->indices.end(), {b, e, c});
        }
      }
    }
  }
  // Triangle adjacency: the cut finds hole boundaries from it in linear time. Directed edges
  // sorted by (from, to); each edge's twin is found by binary search.
  const uint32_t nt = static_cast<uint32_t>(d->indices.size() / 3);
  std::vector<std::pair<uint64_t, uint32_t>> edges;
  edges.reserve(d->indices.size());
  auto key = [](uint32_t a, uint32_t b) { return (static_cast<uint64_t>(a) << 32) | b; };
  for (uint32_t t = 0; t < nt; ++t) {
    for (int k = 0; k < 3; ++k) {
      edges.push_back({key(d->indices[3 * t + k], d->indices[3 * t + (k + 1) % 3]), t});
    }
  }
  std::sort(edges.begin(), edges.end());
  d->corner.resize(d->directions.size());
  for (uint32_t c = 0; c < d->indices.size(); ++c)
    d->corner[d->indices[c]] = c;
  // Vertex adjacency (compressed rows): each undirected edge once from each end.
  d->adjacent_start.assign(d->directions.size() + 1, 0);
  for (const auto& [e, t] : edges)
    ++d->adjacent_start[(e >> 32) + 1];
  for (size_t v = 0; v < d->directions.size(); ++v)
    d->adjacent_start[v + 1] += d->adjacent_start[v];
  d->adjacent.resize(edges.size());
  for (size_t i = 0; i < edges.size(); ++i)
    d->adjacent[i] = static_cast<uint32_t>(edges[i].first & 0xffffffffu);
  d->neighbours.resize(d->indices.size());
  for (uint32_t t = 0; t < nt; ++t) {
    for (int k = 0; k < 3; ++k) {
      uint64_t twin = key(d->indices[3 * t + (k + 1) % 3], d->indices[3 * t + k]);
      auto it =
          std::lower_bound(edges.begin(), edges.end(), std::pair<uint64_t, uint32_t>{twin, 0});
      d->neighbours[3 * t + k] = it->second;
    }
  }
  return d;
}

}  // namespace

int donor_frequency(double radius, double edge_length) {
  return std::max(2, static_cast<int>(std::lround(kEdgeFactor * radius / edge_length)));
}

std::shared_ptr<const DonorSphere> donor_sphere(int frequency) {
  static std::mutex mutex;
  static std::map<int, std::shared_ptr<const DonorSphere>> cache;
  std::lock_guard lock(mutex);
  auto& slot = cache[frequency];
  if (!slot) slot = build(frequency);
  return slot;
}

}  // namespace grotto::mesh
