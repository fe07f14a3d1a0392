#include "client/app/camera_aim.hpp"

#include <algorithm>
#include <cmath>

#include "client/app/options.hpp"

namespace grotto::app {
namespace {

constexpr double kPi = 3.14159265358979323846;

}  // namespace

void look_along(render::Camera& camera, Vec3 f) {
  const double horizontal = std::sqrt(f.x * f.x + f.z * f.z);
  camera.yaw = std::atan2(f.x, -f.z);
  camera.pitch = std::clamp(std::atan2(f.y, horizontal), -89 * kPi / 180, 89 * kPi / 180);
}

void aim_when_known(render::Camera& camera, std::optional<cave::RoomId>& aim_room,
                    const play::Flythrough::Lookup& lookup) {
  if (!aim_room) return;
  const std::optional<cave::Room> room = lookup(*aim_room);
  if (!room) return;
  aim_room.reset();
  const cave::Portal* widest = nullptr;
  for (const auto& portal : room->portals)
    if (widest == nullptr || portal.radius > widest->radius) widest = &portal;
  if (widest != nullptr) {
    look_along(camera, widest->centre - camera.position);
    camera.pitch = std::clamp(camera.pitch, -kPi / 4, kPi / 4);
  }
}

void follow_path(render::Camera& camera, std::optional<cave::RoomId>& aim_room,
                 const play::Flythrough& path, double seconds) {
  // The spawn's aim waits for pump() to take the spawn room's descriptor, but planning the path
  // needs that descriptor too: when the path is planned before the next pump(), the aim would
  // land on the path's pose (seed 7 --flythrough 3 gave one of two pictures run to run).
  aim_room.reset();
  const play::PathPose pose = path.at(kPathSpeed * seconds);
  camera.position = pose.position;
  look_along(camera, pose.forward);
}

}  // namespace grotto::app
