// The wire lod and mesh::Lod count in opposite directions; proto/lod.hpp is the one mapping.
#include <gtest/gtest.h>

#include "proto/lod.hpp"
#include "proto/messages.hpp"

namespace grotto::proto {
namespace {

TEST(ProtoLod, wire_lod_0_is_the_streamed_patch_mesh_and_1_the_detail_mesh) {
  EXPECT_EQ(mesh_lod(0), mesh::Lod::kPatch);
  EXPECT_EQ(mesh_lod(1), mesh::Lod::kDetail);
  // Not the enum's own numbering, which runs the other way.
  EXPECT_NE(static_cast<uint32_t>(mesh::Lod::kPatch), uint32_t{wire_lod(mesh::Lod::kPatch)});
  // The default limits serve exactly the patch mesh.
  EXPECT_EQ(mesh_lod(Limits{}.max_lod), mesh::Lod::kPatch);
}

TEST(ProtoLod, the_mapping_is_a_bijection_and_nothing_past_kMaxWireLod_maps) {
  for (int l = 0; l < mesh::kLodCount; ++l) {
    mesh::Lod lod = static_cast<mesh::Lod>(l);
    EXPECT_LE(wire_lod(lod), kMaxWireLod);
    EXPECT_EQ(mesh_lod(wire_lod(lod)), lod) << mesh::lod_name(lod);
  }
  for (uint32_t wire = 0; wire <= kMaxWireLod; ++wire) {
    ASSERT_TRUE(mesh_lod(wire).has_value()) << wire;
    EXPECT_EQ(wire_lod(*mesh_lod(wire)), wire);
  }
  for (uint32_t wire : {kMaxWireLod + 1, 255u, 256u, 0xffffffffu})
    EXPECT_EQ(mesh_lod(wire), std::nullopt) << wire;
}

}  // namespace
}  // namespace grotto::proto
