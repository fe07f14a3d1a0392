// JSON views of the layout for people and tools (grotto-layout --json). The wire protocol's room
// descriptors use the same field names (see proto/PROTOCOL.md).
#pragma once

#include <string>

#include "common/cave/layout.hpp"

namespace grotto::proto {

// {"id", "sector", "gate", "centre", "radius", "portals": [{"to", "centre", "normal", "radius"}]}
std::string room_json(const cave::Room& room, int indent = -1);
// The same, and what the world's rock made of it: each portal's "section" ({"kind", "up",
// "half_width", "half_height", "slot_depth", "slot_width"}: cave::PassageSection) and the room's
// "geology" at its centre ({"bedding_normal", "dip_degrees", "bed", "bed_thickness",
// "bed_hardness", "joints": [{"normal", "spacing"}], "water_level", "phreatic"}).
std::string room_json(const cave::World& world, const cave::Room& room, int indent = -1);

// {"seed", "sector_size", "lo", "hi", "spawn", "sectors": [...], "rooms": [...]}, each room as
// the world's room_json gives it.
std::string region_json(const cave::World& world, const cave::Region& region, int indent = -1);

}  // namespace grotto::proto
