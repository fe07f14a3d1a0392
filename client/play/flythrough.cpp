#include "client/play/flythrough.hpp"

#include <algorithm>
#include <cmath>
#include <set>

namespace grotto::play {
namespace {

constexpr int kSamplesPerSegment = 16;
// The camera looks at the path this far ahead, as someone walking a passage looks where it
// leads: the tangent alone points at the outer wall of every bend (and of the swerve through
// each room's interior point) until the path has turned.
constexpr double kLookAhead = 4.0;  // metres

// Centripetal Catmull-Rom between p1 and p2 (Barry-Goldman's pyramid): no cusps or loops where
// waypoints bunch up, so the path stays near the straight portal-to-room segments.
Vec3 catmull_rom(Vec3 p0, Vec3 p1, Vec3 p2, Vec3 p3, double u) {
  auto knot = [](double t, Vec3 a, Vec3 b) {
    return t + std::max(std::sqrt(distance(a, b)), 1e-6);
  };
  const double t0 = 0, t1 = knot(t0, p0, p1), t2 = knot(t1, p1, p2), t3 = knot(t2, p2, p3);
  const double t = t1 + (t2 - t1) * u;
  auto lerp = [&](Vec3 a, Vec3 b, double ta, double tb) {
    return a * ((tb - t) / (tb - ta)) + b * ((t - ta) / (tb - ta));
  };
  const Vec3 a1 = lerp(p0, p1, t0, t1), a2 = lerp(p1, p2, t1, t2), a3 = lerp(p2, p3, t2, t3);
  const Vec3 b1 = lerp(a1, a2, t0, t2), b2 = lerp(a2, a3, t1, t3);
  return lerp(b1, b2, t1, t2);
}

}  // namespace

Flythrough Flythrough::plan(Vec3 start, cave::RoomId start_room, const Lookup& lookup,
                            int max_hops) {
  Flythrough f;
  f.waypoints_.push_back(start);
  std::set<cave::RoomId> visited{start_room};
  std::optional<cave::Room> room = lookup(start_room);
  if (!room) f.waiting_for_ = start_room;
  if (room) f.rooms_.push_back(start_room);
  for (int hop = 0; room && hop < max_hops; ++hop) {
    const cave::Portal* widest = nullptr;
    for (const cave::Portal& portal : room->portals) {
      if (visited.count(portal.neighbour)) continue;
      if (widest == nullptr || portal.radius > widest->radius ||
          (portal.radius == widest->radius && portal.neighbour < widest->neighbour))
        widest = &portal;
    }
    if (widest == nullptr) break;  // a dead end: every neighbour visited
    const cave::RoomId next = widest->neighbour;
    std::optional<cave::Room> next_room = lookup(next);
    if (!next_room) {
      f.waiting_for_ = next;
      break;
    }
    f.waypoints_.push_back(widest->centre);
    f.waypoints_.push_back(cave::interior_point(*next_room));
    f.rooms_.push_back(next);
    visited.insert(next);
    room = std::move(next_room);
  }
  f.sample();
  return f;
}

void Flythrough::sample() {
  points_.clear();
  lengths_.clear();
  const size_t n = waypoints_.size();
  if (n == 0) return;
  points_.push_back(waypoints_[0]);
  // Phantom end points reflected through the ends keep the spline's end tangents along the path.
  auto at = [&](long i) {
    if (i < 0) return waypoints_[0] * 2 - waypoints_[std::min<size_t>(1, n - 1)];
    if (i >= static_cast<long>(n)) return waypoints_[n - 1] * 2 - waypoints_[n >= 2 ? n - 2 : 0];
    return waypoints_[static_cast<size_t>(i)];
  };
  for (long i = 0; i + 1 < static_cast<long>(n); ++i)
    for (int s = 1; s <= kSamplesPerSegment; ++s)
      points_.push_back(catmull_rom(at(i - 1), at(i), at(i + 1), at(i + 2),
                                    static_cast<double>(s) / kSamplesPerSegment));
  lengths_.push_back(0);
  for (size_t i = 1; i < points_.size(); ++i)
    lengths_.push_back(lengths_.back() + distance(points_[i - 1], points_[i]));
}

Vec3 Flythrough::point_at(double s) const {
  const size_t i =
      static_cast<size_t>(std::upper_bound(lengths_.begin(), lengths_.end(), s) - lengths_.begin());
  const size_t hi = std::clamp<size_t>(i, 1, points_.size() - 1), lo = hi - 1;
  const double span = lengths_[hi] - lengths_[lo];
  const double u = span > 0 ? std::clamp((s - lengths_[lo]) / span, 0.0, 1.0) : 0;
  return points_[lo] + (points_[hi] - points_[lo]) * u;
}

PathPose Flythrough::at(double distance_along) const {
  PathPose pose;
  if (points_.empty()) return pose;
  pose.position = points_[0];
  const double total = length();
  if (!(total > 0)) return pose;
  double s = std::fmod(std::max(distance_along, 0.0), 2 * total);
  const bool back = s > total;
  if (back) s = 2 * total - s;
  pose.position = point_at(s);
  const size_t i =
      static_cast<size_t>(std::upper_bound(lengths_.begin(), lengths_.end(), s) - lengths_.begin());
  const size_t hi = std::clamp<size_t>(i, 1, points_.size() - 1), lo = hi - 1;
  Vec3 tangent = points_[hi] - points_[lo];
  if (!(grotto::length(tangent) > 0)) return pose;
  tangent = normalize(back ? -tangent : tangent);
  pose.forward = tangent;
  // The gaze: the chord of kLookAhead metres that ends kLookAhead ahead of the camera, or at the
  // path's end when that is nearer (so it never shrinks to nothing there).
  const double reach = std::min(kLookAhead, total);
  const double ahead = back ? std::max(s - reach, 0.0) : std::min(s + reach, total);
  const double behind = back ? ahead + reach : ahead - reach;
  const Vec3 chord = point_at(ahead) - point_at(behind);
  if (!(grotto::length(chord) > 1e-6)) return pose;
  const Vec3 gaze = normalize(chord);
  // Where the path doubles back within the look-ahead, lean towards the travel, continuously,
  // so that the camera never looks backwards (forward . tangent >= 1 - c > 0 below c = 1/2).
  const double c = dot(gaze, tangent);
  pose.forward = normalize(gaze + tangent * std::max(0.0, 1 - 2 * c));
  return pose;
}

}  // namespace grotto::play
