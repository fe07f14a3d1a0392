// The sectors the whole-world sweeps draw (mesh_sweep, mesh_folds): the same seeds give the same
// sectors in every tool, so their counts speak of the same rooms.
#pragma once

#include <cstdint>
#include <optional>
#include <set>
#include <span>
#include <vector>

#include "common/cave/layout.hpp"
#include "common/core/random.hpp"

namespace grotto::bench {

// The block of sectors --from and --to name (x y z each): none when either lies outside the
// sector range or from > to on an axis.
struct SectorBlock {
  cave::SectorCoord lo, hi;
};
inline std::optional<SectorBlock> sector_block(const std::vector<int>& from,
                                               const std::vector<int>& to) {
  SectorBlock b{{from[0], from[1], from[2]}, {to[0], to[1], to[2]}};
  if (!cave::in_range(b.lo) || !cave::in_range(b.hi) || b.lo[0] > b.hi[0] || b.lo[1] > b.hi[1] ||
      b.lo[2] > b.hi[2]) {
    return std::nullopt;
  }
  return b;
}

// `sample` sectors drawn uniformly from [-spread, spread]^3 by (sample_seed, world seed).
inline std::vector<cave::SectorCoord> sample_sectors(uint64_t world_seed, uint64_t sample_seed,
                                                     int sample, int spread) {
  std::vector<cave::SectorCoord> sectors;
  Rng rng(hash_words(sample_seed, world_seed));
  for (int i = 0; i < sample; ++i) {
    cave::SectorCoord s;
    for (int a = 0; a < 3; ++a)
      s[a] = static_cast<int32_t>(rng.below(static_cast<uint32_t>(2 * spread + 1))) - spread;
    sectors.push_back(s);
  }
  return sectors;
}

// Each sector's interior rooms and the gates of its faces, each room once, in draw order.
inline std::vector<cave::Room> rooms_of(const cave::World& world,
                                        std::span<const cave::SectorCoord> sectors) {
  std::vector<cave::Room> rooms;
  std::set<cave::RoomId> seen;
  for (cave::SectorCoord s : sectors) {
    for (cave::Room& r : cave::generate_region(world, s, s).rooms) {
      if (seen.insert(r.id).second) rooms.push_back(std::move(r));
    }
  }
  return rooms;
}

}  // namespace grotto::bench
