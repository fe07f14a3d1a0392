// What a client derives from a room besides its mesh, as one JSON document: the resource
// /extras/v<version>/<seed>/<params>/<lod>/<room id> (proto/PROTOCOL.md, "Room extras over
// HTTP") that the browser viewer reads beside each room frame. The native clients
// derive the same things themselves from what they already hold (cave::room_lights from the
// seed and the room, formations::place from the decoded patch mesh); the viewer asks the server,
// so the world's rules live once, in C++, and never in JavaScript.
#pragma once

#include <cstdint>
#include <span>
#include <string>

#include "common/cave/params.hpp"
#include "common/core/result.hpp"

namespace grotto::server {

// The extras of the room whose frame (as sent, proto/PROTOCOL.md "Binary room frame") is
// `frame`, in world `seed` with the layout parameters `layout` (their floors place the lights):
//   {"room": id, "origin": [x, y, z], "lights": [...], "formations": {"count": n, "data": [...]}}
// Lights are the renderer's (client/render Light: colour x intensity, glow pattern, pattern seed,
// bound sphere); formations are formations::place's, 16 numbers each as formation.vert's
// instance attributes, roots in metres from the frame's origin. Numbers round-trip (%.17g for
// doubles, %.9g for floats). Errors: the frame or its payload does not decode (bad_frame).
// Costs what placement costs: ~1-10 ms a room (a hall the most); call it off the I/O threads.
Result<std::string> room_extras_json(std::span<const uint8_t> frame, uint64_t seed,
                                     const cave::LayoutParams& layout);

}  // namespace grotto::server
