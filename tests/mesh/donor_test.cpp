#include "common/mesh/donor.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <map>

namespace grotto::mesh {
namespace {

TEST(DonorSphere, is_a_closed_outward_facing_geodesic_sphere) {
  for (int n : {2, 5, 17}) {
    auto d = donor_sphere(n);
    ASSERT_EQ(d->directions.size(), static_cast<size_t>(10 * n * n + 2)) << n;
    ASSERT_EQ(d->indices.size(), static_cast<size_t>(3 * 20 * n * n)) << n;
    for (const auto& v : d->directions) {
      EXPECT_NEAR(std::sqrt(v.x * v.x + v.y * v.y + v.z * v.z), 1.0, 1e-6);
    }
    std::map<std::pair<uint32_t, uint32_t>, int> directed;
    for (size_t t = 0; t < d->indices.size(); t += 3) {
      uint32_t a = d->indices[t], b = d->indices[t + 1], c = d->indices[t + 2];
      for (auto e : {std::pair{a, b}, std::pair{b, c}, std::pair{c, a}})
        ++directed[e];
      // Counter-clockwise from outside: the normal points away from the centre.
      auto p = [&](uint32_t i) { return d->directions[i]; };
      double ux = p(b).x - p(a).x, uy = p(b).y - p(a).y, uz = p(b).z - p(a).z;
      double vx = p(c).x - p(a).x, vy = p(c).y - p(a).y, vz = p(c).z - p(a).z;
      double nx = uy * vz - uz * vy, ny = uz * vx - ux * vz, nz = ux * vy - uy * vx;
      EXPECT_GT(nx * p(a).x + ny * p(a).y + nz * p(a).z, 0) << "triangle " << t / 3;
    }
    for (auto& [e, count] : directed) {
      EXPECT_EQ(count, 1);
      EXPECT_EQ(directed.count({e.second, e.first}), 1u) << "edge without a twin";
    }
    ASSERT_EQ(d->corner.size(), d->directions.size()) << n;
    for (uint32_t v = 0; v < d->corner.size(); ++v) {
      ASSERT_LT(d->corner[v], d->indices.size());
      EXPECT_EQ(d->indices[d->corner[v]], v) << "corner of vertex " << v;
    }
  }
}

TEST(DonorSphere, resolution_follows_the_radius) {
  EXPECT_EQ(donor_frequency(2.5, 0.25), 11);
  EXPECT_EQ(donor_frequency(10.0, 0.25), 44);
  EXPECT_EQ(donor_frequency(0.1, 0.25), 2) << "at least frequency 2";
  // Edge length stays near the target for small and big rooms alike.
  for (double radius : {2.5, 5.0, 12.0}) {
    int n = donor_frequency(radius, 0.25);
    auto d = donor_sphere(n);
    double sum = 0;
    for (size_t t = 0; t < d->indices.size(); t += 3) {
      auto a = d->directions[d->indices[t]], b = d->directions[d->indices[t + 1]];
      sum += radius * std::sqrt((a.x - b.x) * (a.x - b.x) + (a.y - b.y) * (a.y - b.y) +
                                (a.z - b.z) * (a.z - b.z));
    }
    EXPECT_NEAR(sum / (d->indices.size() / 3), 0.25, 0.04) << radius;
  }
}

TEST(DonorSphere, is_cached) {
  EXPECT_EQ(donor_sphere(7).get(), donor_sphere(7).get());
}

}  // namespace
}  // namespace grotto::mesh
