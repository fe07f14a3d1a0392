#include "common/cave/layout.hpp"

#include <algorithm>
#include <cassert>
#include <cmath>

#include "common/core/bytes.hpp"
#include "common/core/parallel.hpp"
#include "common/core/random.hpp"

namespace grotto::cave {

std::optional<double> floor_height(const LayoutParams& params, const Sphere& sphere) {
  if (sphere.radius < params.floor_min_radius || params.floor_depth <= 0) return std::nullopt;
  return sphere.centre.y - params.floor_depth * sphere.radius;
}

std::optional<Ceiling> room_ceiling(const LayoutParams& params, const Sphere& sphere) {
  if (!floor_height(params, sphere) || params.ceiling_rise >= 1) return std::nullopt;
  Ceiling c;
  c.spring = sphere.centre.y + params.ceiling_spring * sphere.radius;
  c.bend = params.ceiling_bend * sphere.radius;
  // The sphere's top (spring + (1 - spring) r above the centre) lands ceiling_rise x r above it.
  double above = (1.0 - params.ceiling_spring - 0.5 * params.ceiling_bend) * sphere.radius;
  c.squash = (1.0 - params.ceiling_rise) * sphere.radius / above;
  return c;
}

double Ceiling::lower(double y) const {
  double t = y - spring;
  if (t <= 0) return y;
  double ramp = t < bend ? t * t / (2.0 * bend) : t - 0.5 * bend;
  return y - squash * ramp;
}

namespace {

const Room* find_room(const std::vector<Room>& rooms, RoomId id) {
  auto it = std::lower_bound(rooms.begin(), rooms.end(), id,
                             [](const Room& r, RoomId key) { return r.id < key; });
  return it != rooms.end() && it->id == id ? &*it : nullptr;
}

// A gate's whole record: its portals on the lower sector's side and on the upper's.
Room merge_gate(const SectorLayout& lower, const SectorLayout& upper, RoomId id) {
  const Room* a = find_room(lower.gates, id);
  const Room* b = find_room(upper.gates, id);
  assert(a && b);
  Room out = *a;
  out.portals.insert(out.portals.end(), b->portals.begin(), b->portals.end());
  std::sort(out.portals.begin(), out.portals.end(),
            [](const Portal& p, const Portal& q) { return p.neighbour < q.neighbour; });
  return out;
}

// A sector whose gates could not be linked: never served as if it were whole. validate() keeps
// parameters where this does not happen; reaching it is a bug worth a clear message.
Error disconnected(SectorCoord s) {
  return Error{ErrorCode::kInternal,
               "sector " + to_string(s) + " could not link its gates; its rooms are unavailable"};
}

}  // namespace

Result<World> World::create(uint64_t seed, const LayoutParams& params) {
  if (Status s = validate(params); !s) return s.error();
  return World(seed, params);
}

namespace {
// The World-only forms generate every sector they need.
SectorSource generating(const World& world) {
  return [world](SectorCoord s) {
    return std::make_shared<const SectorLayout>(generate_sector(world, s));
  };
}
}  // namespace

Result<Room> room(const World& world, RoomId id) {
  return room(world, id, generating(world));
}

Result<Room> room(const World& world, RoomId id, const SectorSource& sectors) {
  SectorCoord s = id.sector();
  if (!id.is_gate()) {
    auto layout = sectors(s);
    if (!layout->connected) return disconnected(s);
    if (id.index() >= static_cast<int>(layout->rooms.size())) {
      return not_found("room " + id.to_string() + " does not exist: sector " + to_string(s) +
                       " has " + std::to_string(layout->rooms.size()) + " interior rooms");
    }
    return layout->rooms[id.index()];
  }
  SectorCoord upper_coord = neighbour(s, id.gate_axis(), 1);
  if (!in_range(upper_coord)) {
    return not_found("room " + id.to_string() + " does not exist: the world's edge has no gates");
  }
  // A face's gates are a hash away (face_gates): a missing one costs no sector.
  size_t gate_count = face_gates(world, s, id.gate_axis()).size();
  if (id.index() >= static_cast<int>(gate_count)) {
    return not_found("room " + id.to_string() + " does not exist: that face has " +
                     std::to_string(gate_count) + " gates");
  }
  auto lower = sectors(s);
  auto upper = sectors(upper_coord);
  if (!lower->connected) return disconnected(lower->sector);
  if (!upper->connected) return disconnected(upper->sector);
  return merge_gate(*lower, *upper, id);
}

SectorCoord sector_of(const World& world, Vec3 point) {
  SectorCoord s;
  for (int a = 0; a < 3; ++a) {
    double c = std::floor(point[a] / world.params().sector_size);
    // Out of range (NaN included) maps to a sector beyond the limit, which in_range rejects.
    if (!(c >= -kSectorCoordLimit && c <= kSectorCoordLimit)) c = 2.0 * kSectorCoordLimit;
    s[a] = static_cast<int32_t>(c);
  }
  return s;
}

bool in_space(const Room& room, Vec3 point) {
  if (length_squared(point - room.sphere.centre) > room.sphere.radius * room.sphere.radius)
    return false;
  for (const Portal& p : room.portals) {
    double side = dot(point - p.centre, p.normal);
    if (side > 0 || (side == 0 && p.neighbour < room.id)) return false;
  }
  return true;
}

Vec3 interior_point(const Room& room) {
  Vec3 p = room.sphere.centre;
  for (int pass = 0; pass < 4 && !in_space(room, p); ++pass) {
    for (const Portal& portal : room.portals) {
      double side = dot(p - portal.centre, portal.normal);
      if (side >= 0) p = p - portal.normal * (side + 0.25);
    }
  }
  return p;
}

const Room* room_at(const SectorLayout& layout, Vec3 point) {
  const Room* interior = room_at(layout.rooms, point);
  const Room* gate = room_at(layout.gates, point);
  if (!interior || (gate && gate->id < interior->id)) return gate;
  return interior;
}

std::optional<RoomId> locate(const World& world, Vec3 point) {
  return locate(world, point, generating(world));
}

std::optional<RoomId> locate(const World& world, Vec3 point, const SectorSource& sectors) {
  if (!is_finite(point)) return std::nullopt;
  SectorCoord s = sector_of(world, point);
  if (!in_range(s)) return std::nullopt;
  // Only this sector's side of a gate matters: portals on the other side lie in the other sector.
  auto layout = sectors(s);
  const Room* found = room_at(*layout, point);
  return found ? std::optional<RoomId>(found->id) : std::nullopt;
}

Spawn spawn(const World& world, const SectorSource& sectors) {
  auto layout = sectors({0, 0, 0});
  double half = 0.5 * world.params().sector_size;
  Vec3 centre{half, half, half};
  // Not in a hall (its centre floats metres above the floor) but in a room that opens into one
  // when there is one: the player starts at a hall's entrance. Then the nearest to the centre.
  auto is_hall = [&](const Room& r) { return floor_height(world.params(), r.sphere).has_value(); };
  auto beside_hall = [&](const Room& r) {
    for (const Portal& p : r.portals) {
      const Room* n = find_room(layout->rooms, p.neighbour);
      if (n && is_hall(*n)) return true;
    }
    return false;
  };
  const Room* best = nullptr;
  bool best_beside = false;
  for (const Room& r : layout->rooms) {
    if (is_hall(r)) continue;
    const bool beside = beside_hall(r);
    if (!best || beside > best_beside ||
        (beside == best_beside &&
         length_squared(r.sphere.centre - centre) < length_squared(best->sphere.centre - centre))) {
      best = &r;
      best_beside = beside;
    }
  }
  if (!best && !layout->rooms.empty()) best = &layout->rooms.front();
  // A sector always links its gates with at least one interior room.
  assert(best);
  if (!best) best = &layout->gates.front();
  return {best->id, interior_point(*best)};
}

RoomId spawn_room(const World& world) {
  return spawn(world, generating(world)).room;
}

const Room* Region::find(RoomId id) const {
  return find_room(rooms, id);
}

RegionPlan plan_region(const World& world, SectorCoord lo, SectorCoord hi) {
  RegionPlan plan{lo, hi, {}, {}};
  for (int x = lo.x; x <= hi.x; ++x) {
    for (int y = lo.y; y <= hi.y; ++y) {
      for (int z = lo.z; z <= hi.z; ++z)
        plan.block.push_back({x, y, z});
    }
  }
  auto in_block = [&](SectorCoord s) {
    for (int a = 0; a < 3; ++a) {
      if (s[a] < lo[a] || s[a] > hi[a]) return false;
    }
    return true;
  };
  for (SectorCoord b : plan.block) {
    for (int axis = 0; axis < 3; ++axis) {
      for (int step : {-1, 1}) {
        const SectorCoord beyond = neighbour(b, axis, step);
        if (in_block(beyond)) continue;
        if (!face_gates(world, step > 0 ? b : beyond, axis).empty()) {
          plan.outside.push_back(beyond);
        }
      }
    }
  }
  std::sort(plan.outside.begin(), plan.outside.end());
  plan.outside.erase(std::unique(plan.outside.begin(), plan.outside.end()), plan.outside.end());
  return plan;
}

Region assemble_region(const RegionPlan& plan, std::vector<SectorLayout> layouts) {
  const SectorCoord lo = plan.lo, hi = plan.hi;
  Region region{lo, hi, {}, {}};
  const auto first_outside = layouts.begin() + static_cast<ptrdiff_t>(plan.block.size());
  region.sectors.assign(std::make_move_iterator(layouts.begin()),
                        std::make_move_iterator(first_outside));
  std::vector<RoomId> gate_ids;
  for (const SectorLayout& layout : region.sectors) {
    region.rooms.insert(region.rooms.end(), layout.rooms.begin(), layout.rooms.end());
    for (const Room& g : layout.gates)
      gate_ids.push_back(g.id);
  }
  std::sort(gate_ids.begin(), gate_ids.end());
  gate_ids.erase(std::unique(gate_ids.begin(), gate_ids.end()), gate_ids.end());
  auto layout_of = [&](SectorCoord s) -> const SectorLayout& {
    bool in_block = true;
    for (int a = 0; a < 3; ++a)
      in_block = in_block && s[a] >= lo[a] && s[a] <= hi[a];
    if (in_block) {
      size_t i = ((static_cast<size_t>(s.x - lo.x) * (hi.y - lo.y + 1)) + (s.y - lo.y)) *
                     (hi.z - lo.z + 1) +
                 (s.z - lo.z);
      return region.sectors[i];
    }
    const auto at = std::lower_bound(plan.outside.begin(), plan.outside.end(), s);
    return *(first_outside + (at - plan.outside.begin()));
  };
  for (RoomId id : gate_ids) {
    SectorCoord lower = id.sector();
    SectorCoord upper = neighbour(lower, id.gate_axis(), 1);
    region.rooms.push_back(merge_gate(layout_of(lower), layout_of(upper), id));
  }
  std::sort(region.rooms.begin(), region.rooms.end(),
            [](const Room& a, const Room& b) { return a.id < b.id; });
  return region;
}

Region generate_region(const World& world, SectorCoord lo, SectorCoord hi, int threads) {
  // Every sector at once: each is a pure function of the world and its coordinates.
  const RegionPlan plan = plan_region(world, lo, hi);
  std::vector<SectorCoord> coords = plan.block;
  coords.insert(coords.end(), plan.outside.begin(), plan.outside.end());
  std::vector<SectorLayout> layouts(coords.size());
  for_each_index(coords.size(), threads,
                 [&](size_t i) { layouts[i] = generate_sector(world, coords[i]); });
  return assemble_region(plan, std::move(layouts));
}

void append_bytes(const Room& room, std::vector<unsigned char>& out) {
  le::append(out, room.id.packed());
  le::append_vec3(out, room.sphere.centre);
  le::append_f64(out, room.sphere.radius);
  le::append(out, room.portals.size());
  for (const Portal& p : room.portals) {
    le::append(out, p.neighbour.packed());
    le::append_vec3(out, p.centre);
    le::append_vec3(out, p.normal);
    le::append_f64(out, p.radius);
  }
}

uint64_t digest(const std::vector<Room>& rooms) {
  std::vector<unsigned char> bytes;
  for (const Room& r : rooms)
    append_bytes(r, bytes);
  return fnv1a64(bytes.data(), bytes.size());
}

}  // namespace grotto::cave
