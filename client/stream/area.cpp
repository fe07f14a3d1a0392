#include "client/stream/area.hpp"

#include <limits>

namespace grotto::stream {

std::vector<PlannedRoom> area_rooms(const PortalGraph& graph, cave::RoomId start, Vec3 point,
                                    double radius_m) {
  // The plan's cost in seconds at 1 m/s is the path length in metres; a zero forward vector
  // turns the view weighting off.
  Pose pose;
  pose.position = point;
  pose.forward = {};
  pose.speed = 1.0;
  PlanOptions options;
  options.horizon_s = radius_m >= 0 ? radius_m : 0;  // NaN fails the test too
  options.behind_weight = 0;
  options.max_rooms = std::numeric_limits<size_t>::max();
  return graph.plan(start, pose, options);
}

AreaStatus area_status(const PortalGraph& graph, const RoomStore& store, Vec3 point,
                       double radius_m, uint32_t max_lod) {
  AreaStatus status;
  const auto start = graph.room_at(point);
  if (!start) return status;
  status.located = true;
  for (const PlannedRoom& planned : area_rooms(graph, *start, point, radius_m)) {
    ++status.rooms;
    const auto held = store.find(planned.id);
    if (planned.known && held && held->lod <= max_lod) continue;
    if (status.missing++ == 0) status.first_missing = planned.id;
  }
  status.ready = status.missing == 0;
  return status;
}

}  // namespace grotto::stream
