// The world parameter digest that hello and welcome carry (proto/PROTOCOL.md, "welcome.params"):
// 64-bit FNV-1a over canonical little-endian bytes, so every build on every platform computes the
// same digest for the same parameters. Two worlds with the same seed and digest have the same
// rooms; clients compare digests for equality and may key caches on (seed, digest).
#pragma once

#include <cstdint>
#include <span>
#include <string_view>

#include "common/cave/params.hpp"
#include "common/mesh/params.hpp"

namespace grotto::proto {

// Every field of the layout parameters, in declaration order, character names included.
uint64_t layout_params_digest(const cave::LayoutParams& params);

// Folds more bytes into a digest: a server adds the mesh and codec settings that also shape the
// rooms it sends, each serialized canonically (fixed order, little-endian, doubles as IEEE bits).
uint64_t fold_digest(uint64_t digest, std::span<const uint8_t> bytes);

// The version of the rock's relief and formations (shaders/relief.glsl's relief_at: what the
// client draws and engines evaluate for collision), folded into the world digest. No room's bytes
// depend on it, yet it is part of the world. A test pins relief_at's values at sample points to
// this version (tests/client/play/relief_test.cpp): a change of the relief fails it until the
// version moves on, while a change of how it is drawn (relief_at_sampled's filtering) does not.
inline constexpr std::string_view kReliefVersion = "grotto.relief.v4";
// The version of the formations (common/formations/formations.hpp: where a room's stalactites,
// stalagmites, soda straws, columns, draperies and a hall's fallen blocks stand and what shape
// each has), folded likewise: what the client draws and collides with, and what engines and the
// glb export place.
inline constexpr std::string_view kFormationsVersion = "grotto.formations.v4";

// The digest a server announces in welcome.params: the layout's, folded with every mesh setting
// that also shapes the rooms (lods, octaves, rim, big-room and channel settings), doubles as IEEE
// bits, little-endian, the world's light placement, the relief's version (kReliefVersion) and the
// formations' (kFormationsVersion).
uint64_t world_params_digest(const cave::LayoutParams& layout, const mesh::MeshParams& mesh);

}  // namespace grotto::proto
