#include "proto/layout_json.hpp"

#include <nlohmann/json.hpp>

namespace grotto::proto {
namespace {

using nlohmann::json;

json vec(Vec3 v) {
  return json::array({v.x, v.y, v.z});
}
json sector(cave::SectorCoord s) {
  return json::array({s.x, s.y, s.z});
}

json room_value(const cave::Room& r) {
  json portals = json::array();
  for (const cave::Portal& p : r.portals) {
    portals.push_back({{"to", p.neighbour.to_string()},
                       {"centre", vec(p.centre)},
                       {"normal", vec(p.normal)},
                       {"radius", p.radius}});
  }
  return {{"id", r.id.to_string()},    {"sector", sector(r.id.sector())},
          {"gate", r.id.is_gate()},    {"centre", vec(r.sphere.centre)},
          {"radius", r.sphere.radius}, {"portals", std::move(portals)}};
}

}  // namespace

std::string room_json(const cave::Room& room, int indent) {
  return room_value(room).dump(indent);
}

std::string region_json(const cave::World& world, const cave::Region& region, int indent) {
  json sectors = json::array();
  for (const cave::SectorLayout& s : region.sectors) {
    json weights = json::object();
    for (int k = 0; k < cave::kCharacterCount; ++k) {
      weights[world.params().characters[k].name] = s.character.weights[k];
    }
    sectors.push_back({{"sector", sector(s.sector)},
                       {"character", s.character.blend.name},
                       {"weights", std::move(weights)},
                       {"rooms", s.rooms.size()},
                       {"gates", s.gates.size()},
                       {"connected", s.connected}});
  }
  json rooms = json::array();
  for (const cave::Room& r : region.rooms)
    rooms.push_back(room_value(r));
  json out = {{"seed", world.seed()},
              {"sector_size", world.params().sector_size},
              {"lo", sector(region.lo)},
              {"hi", sector(region.hi)},
              {"spawn", cave::spawn_room(world).to_string()},
              {"sectors", std::move(sectors)},
              {"rooms", std::move(rooms)}};
  return out.dump(indent);
}

}  // namespace grotto::proto
