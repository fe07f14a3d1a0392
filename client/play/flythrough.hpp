// A deterministic scripted path through the cave, for grotto-client's --flythrough and --bench:
// from a start point, room after room through the widest portal to a room not visited yet (ties
// by neighbour id), through each portal's centre and the next room's interior point, smoothed
// with a centripetal Catmull-Rom spline and walked at constant speed. It depends only on the
// room descriptors along the way (a pure function of the world), not on what has streamed in.
#pragma once

#include <functional>
#include <optional>
#include <vector>

#include "common/cave/layout.hpp"
#include "common/core/vec3.hpp"

namespace grotto::play {

struct PathPose {
  Vec3 position;
  Vec3 forward{0, 0, -1};  // unit
};

class Flythrough {
 public:
  // The known descriptor of a room, or nullopt.
  using Lookup = std::function<std::optional<cave::Room>(cave::RoomId)>;
  // The path from `start` in `start_room` over at most max_hops portals. When the descriptor of
  // the next room is not known yet the path stops short and waiting_for() names that room: a
  // caller that wants the whole path streams it in and plans again.
  static Flythrough plan(Vec3 start, cave::RoomId start_room, const Lookup& lookup, int max_hops);

  const std::vector<Vec3>& waypoints() const { return waypoints_; }
  const std::vector<cave::RoomId>& rooms() const { return rooms_; }  // in path order
  std::optional<cave::RoomId> waiting_for() const { return waiting_for_; }
  double length() const { return lengths_.empty() ? 0 : lengths_.back(); }
  // The pose `distance` metres along the path, there and back again (ping-pong) beyond its end;
  // forward looks a few metres ahead along the path, never against the direction of travel.
  PathPose at(double distance) const;

 private:
  void sample();                  // the spline as a polyline with cumulative lengths
  Vec3 point_at(double s) const;  // the polyline's point s metres from its start, s in [0, length]

  std::vector<Vec3> waypoints_;
  std::vector<cave::RoomId> rooms_;
  std::optional<cave::RoomId> waiting_for_;
  std::vector<Vec3> points_;
  std::vector<double> lengths_;
};

}  // namespace grotto::play
