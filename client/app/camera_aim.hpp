// Which way grotto-client's camera looks when neither the mouse nor the player turns it: at the
// spawn point through the spawn room's widest portal, and on the scripted path (--flythrough,
// --bench) along the path. No GL and no stream, so the order of the two is tested headless
// (tests/client/render/camera_aim_test.cpp).
#pragma once

#include <optional>

#include "client/play/flythrough.hpp"
#include "client/render/renderer.hpp"
#include "common/cave/room_id.hpp"
#include "common/core/vec3.hpp"

namespace grotto::app {

// Turns the camera to look along f (any non-zero length), its pitch within ±89°.
void look_along(render::Camera& camera, Vec3 f);

// At the spawn point the camera looks through the spawn room's widest portal, into the cave
// rather than at the nearest wall, once the room's descriptor has arrived: when lookup knows
// *aim_room, turns the camera (pitch within ±45°) and clears aim_room. Nothing while it is empty.
void aim_when_known(render::Camera& camera, std::optional<cave::RoomId>& aim_room,
                    const play::Flythrough::Lookup& lookup);

// The camera `seconds` along the path at kPathSpeed. From here on the path owns the camera, so an
// aim still waiting for its room is dropped: taken later it would turn the camera off the path.
void follow_path(render::Camera& camera, std::optional<cave::RoomId>& aim_room,
                 const play::Flythrough& path, double seconds);

}  // namespace grotto::app
