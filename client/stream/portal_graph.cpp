#include "client/stream/portal_graph.hpp"

#include <algorithm>
#include <bit>
#include <cassert>
#include <cmath>
#include <cstdio>
#include <set>
#include <utility>

namespace grotto::stream {
namespace {

bool same_bits(double a, double b) {
  return std::bit_cast<uint64_t>(a) == std::bit_cast<uint64_t>(b);
}
bool same_bits(Vec3 a, Vec3 b) {
  return same_bits(a.x, b.x) && same_bits(a.y, b.y) && same_bits(a.z, b.z);
}

std::string format_vec(Vec3 v) {
  char buf[96];
  std::snprintf(buf, sizeof buf, "(%.17g, %.17g, %.17g)", v.x, v.y, v.z);
  return buf;
}

const cave::Portal* portal_to(const cave::Room& room, cave::RoomId to) {
  for (const cave::Portal& p : room.portals)
    if (p.neighbour == to) return &p;
  return nullptr;
}

Error bad_frame(std::string message) {
  return {ErrorCode::kBadFrame, std::move(message)};
}

}  // namespace

// Both sides of portal i of `room` as the layout makes them: the two rooms compute the disc once
// and negate its normal for one side (common/cave/sector.cpp), so every double is bit-identical
// and the normals are exact negations. Checked on real sectors by
// tests/client/portal_graph_test.cpp (portal_sides_are_bit_identical_in_real_sectors).
Status check_portal_sides(const cave::Room& room, size_t i, const cave::Room& other) {
  assert(i < room.portals.size());
  const cave::Portal& p = room.portals[i];
  const std::string where = "room " + room.id.to_string() + " portal " + std::to_string(i) +
                            " to " + other.id.to_string();
  const cave::Portal* q = portal_to(other, room.id);
  if (!q) return bad_frame(where + ": the neighbour has no portal back to this room");
  if (!same_bits(p.centre, q->centre))
    return bad_frame(where + ": centre " + format_vec(p.centre) + " differs from the neighbour's " +
                     format_vec(q->centre));
  if (!same_bits(p.radius, q->radius))
    return bad_frame(where + ": radius " + std::to_string(p.radius) +
                     " differs from the neighbour's " + std::to_string(q->radius));
  if (!same_bits(p.normal, -q->normal))
    return bad_frame(where + ": normal " + format_vec(p.normal) +
                     " is not the negation of the neighbour's " + format_vec(q->normal));
  return {};
}

Status PortalGraph::add(const cave::Room& room) {
  std::set<cave::RoomId> listed;
  for (size_t i = 0; i < room.portals.size(); ++i) {
    const cave::RoomId to = room.portals[i].neighbour;
    if (to == room.id)
      return bad_frame("room " + room.id.to_string() + " portal " + std::to_string(i) +
                       " leads to the room itself");
    if (!listed.insert(to).second)
      return bad_frame("room " + room.id.to_string() + " has two portals to " + to.to_string());
    auto it = rooms_.find(to);
    if (it == rooms_.end()) continue;
    if (Status s = check_portal_sides(room, i, it->second); !s) return s;
  }
  // The other direction: a known room that leads here must be listed back, or the graph would
  // depend on the order rooms arrived in.
  if (auto it = referrers_.find(room.id); it != referrers_.end()) {
    for (cave::RoomId id : it->second) {
      if (id == room.id || listed.count(id)) continue;
      return bad_frame("room " + room.id.to_string() + " has no portal to " + id.to_string() +
                       ", which has a portal to it");
    }
  }
  if (auto old = rooms_.find(room.id); old != rooms_.end()) unlink(old->second);
  for (const auto& p : room.portals)
    referrers_[p.neighbour].insert(room.id);
  rooms_.insert_or_assign(room.id, room);
  return {};
}

void PortalGraph::unlink(const cave::Room& room) {
  for (const auto& p : room.portals) {
    auto it = referrers_.find(p.neighbour);
    if (it == referrers_.end()) continue;
    it->second.erase(room.id);
    if (it->second.empty()) referrers_.erase(it);
  }
}

void PortalGraph::remove(cave::RoomId id) {
  auto it = rooms_.find(id);
  if (it == rooms_.end()) return;
  unlink(it->second);
  rooms_.erase(it);
}

void PortalGraph::clear() {
  rooms_.clear();
  referrers_.clear();
}

const cave::Room* PortalGraph::find(cave::RoomId id) const {
  auto it = rooms_.find(id);
  return it == rooms_.end() ? nullptr : &it->second;
}

std::optional<cave::RoomId> PortalGraph::room_at(Vec3 point) const {
  // The cave's one rule over the rooms known: a room whose neighbour is not known yet still
  // gives up the cap beyond that portal.
  const cave::Room* r = cave::room_at(
      rooms_, point, [](const auto& entry) -> const cave::Room& { return entry.second; });
  if (!r) return std::nullopt;
  return r->id;
}

std::vector<PlannedRoom> PortalGraph::plan(cave::RoomId start, const Pose& pose,
                                           const PlanOptions& options) const {
  std::vector<PlannedRoom> out;
  // max_rooms 0 plans nothing, not even the start room: "never more rooms than this" wins.
  if (options.max_rooms == 0) return out;
  const double speed = pose.speed >= kMinSpeed ? pose.speed : kMinSpeed;  // NaN: kMinSpeed too
  const double forward_length = length(pose.forward);

  // The first hop's view weighting: 1 towards pose.forward, 1 + behind_weight straight behind.
  auto view_factor = [&](Vec3 target) {
    const Vec3 d = target - pose.position;
    const double d_length = length(d);
    if (!(forward_length > 0) || !(d_length > 0)) return 1.0;
    const double c = std::clamp(dot(pose.forward, d) / (forward_length * d_length), -1.0, 1.0);
    return 1.0 + options.behind_weight * (1.0 - c) / 2.0;
  };

  struct Node {
    double seconds = 0;
    Vec3 entry;  // where the cheapest path enters the room (a portal centre; the player at start)
    bool settled = false;
  };
  std::map<cave::RoomId, Node> nodes;
  // Dijkstra's frontier ordered by (seconds, id): ties settle in id order, so plans are
  // deterministic and already sorted as the contract asks.
  std::set<std::pair<double, cave::RoomId>> frontier;
  nodes[start] = Node{0.0, pose.position, false};
  frontier.insert({0.0, start});

  while (!frontier.empty() && out.size() < options.max_rooms) {
    auto [seconds, id] = *frontier.begin();
    frontier.erase(frontier.begin());
    // The start room is in every plan; the others only within the horizon.
    if (id != start && !(seconds <= options.horizon_s)) break;
    Node& node = nodes[id];
    node.settled = true;
    const cave::Room* room = find(id);
    out.push_back({id, seconds, room != nullptr});
    if (!room) continue;  // unknown: a leaf until its frame brings its portals
    const Vec3 from = node.entry;
    for (const cave::Portal& p : room->portals) {
      double hop = distance(from, p.centre) / speed;
      if (id == start) hop *= view_factor(p.centre);
      const double cost = seconds + hop;
      auto [it, fresh] = nodes.try_emplace(p.neighbour, Node{cost, p.centre, false});
      if (!fresh) {
        if (it->second.settled || !(cost < it->second.seconds)) continue;
        frontier.erase({it->second.seconds, p.neighbour});
        it->second.seconds = cost;
        it->second.entry = p.centre;
      }
      frontier.insert({cost, p.neighbour});
    }
  }
  return out;
}

}  // namespace grotto::stream
