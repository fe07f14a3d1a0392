// JSON views of the layout for people and tools (grotto-layout --json). The wire protocol's room
// descriptors use the same field names (see proto/PROTOCOL.md).
#pragma once

#include <string>

#include "common/cave/layout.hpp"

namespace grotto::proto {

// {"id", "sector", "gate", "centre", "radius", "portals": [{"to", "centre", "normal", "radius"}]}
std::string room_json(const cave::Room& room, int indent = -1);

// {"seed", "sector_size", "lo", "hi", "spawn", "sectors": [...], "rooms": [...]}
std::string region_json(const cave::World& world, const cave::Region& region, int indent = -1);

}  // namespace grotto::proto
