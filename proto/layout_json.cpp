#include "proto/layout_json.hpp"

#include <nlohmann/json.hpp>

#include "common/cave/geology.hpp"

namespace grotto::proto {
namespace {

using nlohmann::json;

json vec(Vec3 v) {
  return json::array({v.x, v.y, v.z});
}
json sector(cave::SectorCoord s) {
  return json::array({s.x, s.y, s.z});
}

json section_value(const cave::PassageSection& s) {
  return {{"kind", cave::section_kind_name(s.kind)},
          {"up", vec(s.up)},
          {"half_width", s.half_width},
          {"half_height", s.half_height},
          {"slot_depth", s.slot_depth},
          {"slot_width", s.slot_width},
          {"widen", s.widen},
          {"deepen", s.deepen}};
}

json geology_value(const cave::Geology& g) {
  json joints = json::array();
  for (int i = 0; i < g.joint_count; ++i) {
    joints.push_back({{"normal", vec(g.joints[i].normal)}, {"spacing", g.joints[i].spacing}});
  }
  return {{"bedding_normal", vec(g.bedding_normal)},
          {"dip_degrees", g.dip_degrees},
          {"bed", g.bed},
          {"bed_thickness", g.bed_thickness},
          {"bed_hardness", g.bed_hardness},
          {"joints", std::move(joints)},
          {"water_level", g.water_level},
          {"phreatic", g.phreatic}};
}

// With a world, each portal says its section and the room the rock at its centre.
json room_value(const cave::Room& r, const cave::World* world) {
  json portals = json::array();
  for (const cave::Portal& p : r.portals) {
    json portal = {{"to", p.neighbour.to_string()},
                   {"centre", vec(p.centre)},
                   {"normal", vec(p.normal)},
                   {"radius", p.radius}};
    if (world) {
      portal["section"] =
          section_value(cave::passage_section(*world, p.centre, p.normal, p.radius));
    }
    portals.push_back(std::move(portal));
  }
  json room = {{"id", r.id.to_string()},    {"sector", sector(r.id.sector())},
               {"gate", r.id.is_gate()},    {"centre", vec(r.sphere.centre)},
               {"radius", r.sphere.radius}, {"portals", std::move(portals)}};
  if (world) room["geology"] = geology_value(cave::geology_at(*world, r.sphere.centre));
  return room;
}

}  // namespace

std::string room_json(const cave::Room& room, int indent) {
  return room_value(room, nullptr).dump(indent);
}

std::string room_json(const cave::World& world, const cave::Room& room, int indent) {
  return room_value(room, &world).dump(indent);
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
    rooms.push_back(room_value(r, &world));
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
