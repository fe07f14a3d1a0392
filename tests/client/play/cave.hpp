// Real rooms for play_tests, as a client holds them: sector (0,0,0) of seed 7 built with the CPU
// reference at the patch level, encoded by the room codec and decoded with the frame's limits.
// Built once per test binary.
#pragma once

#include <map>
#include <vector>

#include "client/stream/room_store.hpp"
#include "common/cave/layout.hpp"
#include "common/core/vec3.hpp"

namespace grotto::play::test {

struct Cave {
  std::map<cave::RoomId, stream::ReadyRoom> rooms;  // every room of the sector and its gates
  cave::RoomId spawn_room = cave::RoomId::interior({0, 0, 0}, 0);
  Vec3 spawn;               // the server's spawn point (cave::spawn)
  double spawn_radius = 0;  // the spawn room's sphere radius
};

const Cave& sector_zero();

}  // namespace grotto::play::test
