#include "common/mesh/rim.hpp"
#include "common/cave/geology.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cstdio>

#include "common/core/grid.hpp"

namespace grotto::mesh {
namespace {

class RimTest : public ::testing::Test {
 protected:
  cave::World world = cave::World::create(77, cave::LayoutParams{}).value();
  MeshContext ctx = MeshContext::create(world, MeshParams{}).value();
};

TEST_F(RimTest, both_rooms_compute_the_same_loop_bit_for_bit) {
  cave::Region region = cave::generate_region(world, {0, 0, 0}, {0, 0, 0});
  int checked = 0;
  for (const cave::Room& r : region.rooms) {
    for (const cave::Portal& p : r.portals) {
      const cave::Room* n = region.find(p.neighbour);
      if (!n || !(r.id < n->id)) continue;
      const cave::Portal* back = nullptr;
      for (const cave::Portal& q : n->portals) {
        if (q.neighbour == r.id) back = &q;
      }
      ASSERT_NE(back, nullptr);
      for (Lod lod : {Lod::kDetail, Lod::kPatch}) {
        RimLoop a = canonical_rim(ctx, r, p, lod);
        RimLoop b = canonical_rim(ctx, *n, *back, lod);
        ASSERT_EQ(a.positions.size(), b.positions.size());
        for (size_t k = 0; k < a.positions.size(); ++k) {
          EXPECT_EQ(a.positions[k], b.positions[k]);
          EXPECT_EQ(a.normals[k].x, b.normals[k].x);
          EXPECT_EQ(a.normals[k].y, b.normals[k].y);
          EXPECT_EQ(a.normals[k].z, b.normals[k].z);
        }
      }
      ++checked;
    }
  }
  EXPECT_GT(checked, 50);
}

TEST_F(RimTest, loops_lie_on_the_grid_around_their_portal) {
  cave::Room room = cave::room(world, cave::spawn_room(world)).value();
  for (const cave::Portal& p : room.portals) {
    RimLoop loop = canonical_rim(ctx, room, p, Lod::kPatch);
    EXPECT_GE(loop.positions.size(), 8u);
    const cave::PassageSection section = cave::passage_section(world, p.centre, p.normal, p.radius);
    EXPECT_EQ(static_cast<int>(loop.positions.size()),
              rim_vertex_count(p.radius * std::max(1.0, cave::section_perimeter(section)), 0.56));
    double area = 0;
    for (size_t k = 0; k < loop.positions.size(); ++k) {
      Vec3 v = loop.positions[k];
      EXPECT_TRUE(grid::on_grid(v.x) && grid::on_grid(v.y) && grid::on_grid(v.z));
      // In the portal plane (to the grid's precision), on its passage's section: moved by the rim
      // noise (12 % of the radius) and by at most the surface octaves (0.78 m at patch level),
      // never narrower than rim_min_radius (1.05 m) or the section itself allows.
      EXPECT_LT(std::abs(dot(v - p.centre, p.normal)), grid::kStep);
      double r = length(v - p.centre);
      EXPECT_GT(r, std::min(1.05, p.radius * cave::section_narrow(section) * 0.88) - grid::kStep);
      EXPECT_LT(r, p.radius * cave::section_reach(section) * 1.2 + 0.8);
      Vec3 w = loop.positions[(k + 1) % loop.positions.size()];
      Vec3 a = v - p.centre, b = w - p.centre;
      area += dot(Vec3{a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x},
                  loop.normal);
    }
    EXPECT_GT(area, 0) << "counter-clockwise about the canonical normal";
  }
}

TEST_F(RimTest, rims_move_with_the_surface_noise_but_stay_wide_enough) {
  // The walls run rough into the rim instead of smoothing into a collar around it
  // (deform_core.h, grotto_rim_noise): each rim vertex moves in the plane by the surface noise
  // where it sits, by the same amount from both rooms, never to less than rim_min_radius.
  MeshParams still;
  still.octave_amplitude.fill(0.0);
  MeshContext plain = MeshContext::create(world, still).value();
  cave::Region region = cave::generate_region(world, {0, 0, 0}, {0, 0, 0});
  double moved = 0;
  int count = 0;
  for (const cave::Room& r : region.rooms) {
    for (const cave::Portal& p : r.portals) {
      RimLoop rough = canonical_rim(ctx, r, p, Lod::kPatch);
      RimLoop smooth = canonical_rim(plain, r, p, Lod::kPatch);
      ASSERT_EQ(rough.positions.size(), smooth.positions.size());
      for (size_t k = 0; k < rough.positions.size(); ++k) {
        double radius = length(rough.positions[k] - p.centre);
        moved += std::abs(radius - length(smooth.positions[k] - p.centre));
        ++count;
        const double narrowest =
            p.radius *
            cave::section_narrow(cave::passage_section(world, p.centre, p.normal, p.radius)) *
            (1 - ctx.params().rim_amplitude);
        EXPECT_GT(radius, std::min(ctx.params().rim_min_radius, narrowest) - grid::kStep)
            << r.id.to_string();
      }
    }
  }
  ASSERT_GT(count, 1000);
  std::printf("rims moved %.3f m on average over %d vertices\n", moved / count, count);
  // The patch octaves move a rim by 0.096 m on average here (seed 77, sector 0.0.0); rims without
  // them would not move at all.
  EXPECT_GT(moved / count, 0.05);
}

TEST_F(RimTest, every_rim_vertex_lies_within_the_rim_reach) {
  // The renderer's fog caps and portal culling cover an opening out to rim_reach.
  cave::Region region = cave::generate_region(world, {0, 0, 0}, {0, 0, 0});
  double closest = 1e300;
  for (const cave::Room& r : region.rooms) {
    for (const cave::Portal& p : r.portals) {
      const double reach = rim_reach(ctx.params(), p.radius);
      for (Lod lod : {Lod::kDetail, Lod::kPatch}) {
        for (Vec3 v : canonical_rim(ctx, r, p, lod).positions) {
          EXPECT_LE(length(v - p.centre), reach + grid::kStep) << r.id.to_string();
          closest = std::min(closest, reach - length(v - p.centre));
        }
      }
    }
  }
  std::printf("the farthest rim vertex is %.3f m inside its rim reach\n", closest);
}

}  // namespace
}  // namespace grotto::mesh
