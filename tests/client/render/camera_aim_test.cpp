// Which way grotto-client's camera looks before the mouse or the player turns it (pure: no GL, no
// network), on the real layout of seed 7, the world of the gallery's flythrough that came out in
// one of two views run to run.
#include "client/app/camera_aim.hpp"

#include <gtest/gtest.h>

#include "client/app/options.hpp"
#include "common/cave/layout.hpp"

namespace grotto::app {
namespace {

struct Seven {
  cave::World world = cave::World::create(7, cave::LayoutParams{}).value();
  cave::RoomId spawn_room = cave::spawn_room(world);
  Vec3 spawn = cave::interior_point(cave::room(world, spawn_room).value());
  // Every descriptor is known, as once the spawn room and the path's rooms have streamed in.
  play::Flythrough::Lookup lookup = [this](cave::RoomId id) -> std::optional<cave::Room> {
    auto room = cave::room(world, id);
    return room ? std::optional<cave::Room>(room.value()) : std::nullopt;
  };
};

render::Camera at(Vec3 position) {
  render::Camera camera;
  camera.position = position;
  return camera;
}

TEST(CameraAim, the_spawn_aim_waits_for_its_room_then_looks_through_the_widest_portal) {
  const Seven w;
  render::Camera camera = at(w.spawn);
  std::optional<cave::RoomId> aim = w.spawn_room;
  aim_when_known(camera, aim, [](cave::RoomId) { return std::optional<cave::Room>(); });
  EXPECT_EQ(aim, w.spawn_room) << "still waiting for the room";
  EXPECT_EQ(camera.yaw, 0);
  EXPECT_EQ(camera.pitch, 0);

  aim_when_known(camera, aim, w.lookup);
  EXPECT_FALSE(aim);
  const cave::Room room = w.lookup(w.spawn_room).value();
  const cave::Portal* widest = &room.portals.front();
  for (const auto& portal : room.portals)
    if (portal.radius > widest->radius) widest = &portal;
  render::Camera expected = at(w.spawn);
  look_along(expected, widest->centre - w.spawn);
  EXPECT_DOUBLE_EQ(camera.yaw, expected.yaw);
  EXPECT_LE(std::abs(camera.pitch), 3.14159265358979323846 / 4 + 1e-12);
}

// The race behind the two views: pump() takes the spawn point and sets the aim; the path, planned
// from the same descriptors, can be followed before the next pump() takes the aim. Whichever
// order the stream's timing gives, the camera must end on the path's pose.
TEST(CameraAim, an_aim_still_waiting_when_the_path_begins_leaves_the_camera_on_the_path) {
  const Seven w;
  const play::Flythrough path = play::Flythrough::plan(w.spawn, w.spawn_room, w.lookup, kPathHops);
  ASSERT_FALSE(path.waiting_for());
  constexpr double kSeconds = 3;  // the gallery's --flythrough 3
  const play::PathPose pose = path.at(kPathSpeed * kSeconds);
  render::Camera on_path = at(pose.position);
  look_along(on_path, pose.forward);

  // The aim's view from that place differs from the path's, so the test can fail.
  render::Camera aimed = on_path;
  std::optional<cave::RoomId> aim = w.spawn_room;
  aim_when_known(aimed, aim, w.lookup);
  ASSERT_GT(std::abs(aimed.yaw - on_path.yaw), 0.1);

  for (bool aim_first : {true, false}) {
    SCOPED_TRACE(aim_first ? "aim taken before the path" : "path followed before the aim");
    render::Camera camera = at(w.spawn);
    aim = w.spawn_room;
    if (aim_first) aim_when_known(camera, aim, w.lookup);
    follow_path(camera, aim, path, kSeconds);
    EXPECT_FALSE(aim) << "the path owns the camera";
    aim_when_known(camera, aim, w.lookup);  // the next pump()
    EXPECT_EQ(camera.position, on_path.position);
    EXPECT_EQ(camera.yaw, on_path.yaw);
    EXPECT_EQ(camera.pitch, on_path.pitch);
  }
}

}  // namespace
}  // namespace grotto::app
