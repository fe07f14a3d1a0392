// The parameter digest is canonical (pinned, so a change of encoding is a deliberate change of
// every deployed world's digest) and sees every field.
#include <gtest/gtest.h>

#include <vector>

#include "proto/world_digest.hpp"

namespace grotto::proto {
namespace {

TEST(WorldDigest, default_parameters_have_a_pinned_digest) {
  // Changing this value changes every world's digest: clients drop their caches. Do it only
  // with a change to the layout parameters or their canonical form.
  // Changed by halls and floors (grotto.layout.v2), then ceilings (grotto.layout.v3).
  EXPECT_EQ(layout_params_digest(cave::LayoutParams{}), 0x9c8782f0f3856b30ull);
}

TEST(WorldDigest, every_field_changes_the_digest) {
  const cave::LayoutParams base;
  std::vector<cave::LayoutParams> variants(15, base);
  variants[0].sector_size += 1;
  variants[1].gates_max += 1;
  variants[2].min_portal_radius = std::nextafter(base.min_portal_radius, 2.0);
  variants[3].region_sharpness += 1;
  variants[4].characters[0].name = "mazes";
  variants[5].characters[2].bias.y += 0.125;
  variants[6].characters[1].loops += 1;
  variants[7].characters[1].tunnel_chance = 0.25;
  variants[8].characters[0].hall_probability = 0.5;
  variants[9].characters[2].hall_radius_max -= 1;
  variants[10].floor_depth = 0.25;
  variants[11].floor_min_radius = 10;
  variants[12].ceiling_spring = 0.25;
  variants[13].ceiling_bend = 0.25;
  variants[14].ceiling_rise = 0.55;
  const uint64_t d = layout_params_digest(base);
  for (std::size_t i = 0; i < variants.size(); ++i) {
    EXPECT_NE(layout_params_digest(variants[i]), d) << "variant " << i;
  }
}

TEST(WorldDigest, folding_more_settings_changes_it) {
  const uint64_t d = layout_params_digest(cave::LayoutParams{});
  const uint8_t mesh_settings[] = {1, 2, 3};
  EXPECT_NE(fold_digest(d, mesh_settings), d);
  EXPECT_EQ(fold_digest(d, mesh_settings), fold_digest(d, mesh_settings));
}

TEST(WorldDigest, the_servers_digest_is_pinned_and_sees_the_mesh_settings) {
  // welcome.params of a server with default settings: a change here changes every deployed
  // world's digest, so make it only with a change to the parameters or their canonical form.
  const cave::LayoutParams layout;
  const mesh::MeshParams mesh;
  const uint64_t d = world_params_digest(layout, mesh);
  // Changed when the digest folded in the world grid (1/64 m since then); then by the
  // deformation's version 2 (halls keep their sphere, floors, the axis fade, donor caps), then
  // the world's lights (cave/lights.hpp: grotto.lights.v1 and its parameters), then the halls'
  // ceilings and larger halls (grotto.layout.v3, grotto.mesh.v3, grotto.lights.v2), then the
  // patch level's donor cap 28 -> 24 (a hall's cost), then the relief's version (kReliefVersion:
  // the relief and formations engines evaluate; no room changed), then its version 2
  // (stalagmites from cones to candles), then the formations as geometry (grotto.relief.v3,
  // grotto.formations.v1), then the flowstone's irregular edges (grotto.relief.v4), then
  // draperies (grotto.formations.v2), then the world's geology (grotto.geology.v1), then rims
  // as passage sections, passages that grow between their ends and halls that step along their
  // beds (grotto.mesh.v5, grotto.geology.v2), and the halls' fallen blocks
  // (grotto.formations.v3), then passages whose middles take their own section's shape
  // (grotto.mesh.v6, grotto.geology.v3), then formations along drip lines
  // (grotto.formations.v4).
  EXPECT_EQ(d, 0x7a58bce46eb33930ull);
  EXPECT_NE(d, layout_params_digest(layout));
  std::vector<mesh::MeshParams> variants(12, mesh);
  variants[0].lods[0].edge_length += 0.125;
  variants[1].lods[1].octaves += 1;
  variants[2].octave_frequency[0] *= 2;
  variants[3].rim_amplitude += 0.01;
  variants[4].tension += 0.125;
  variants[5].mineral_frequency *= 2;
  variants[6].lods[1].max_frequency -= 1;
  variants[7].axis_fade_edges = 2;
  variants[8].keep_distance = 3;
  variants[9].wall_allow = 0.5;
  variants[10].floor_amplitude = 0.5;
  variants[11].floor_frequency *= 2;
  for (std::size_t i = 0; i < variants.size(); ++i) {
    EXPECT_NE(world_params_digest(layout, variants[i]), d) << "mesh variant " << i;
  }
  cave::LayoutParams other = layout;
  other.sector_size += 1;
  EXPECT_NE(world_params_digest(other, mesh), d);
}

}  // namespace
}  // namespace grotto::proto
