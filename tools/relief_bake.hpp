// The GPU's relief baked into a room mesh (grotto-layout --bake-relief): every vertex moved as
// shaders/room.tese moves a tessellated point, through the same function (shaders/relief.glsl,
// compiled as C++ by shaders/relief.hpp): the rock and flowstone along the normal, stalactites
// and stalagmites plumb. An engine that imports the file gets the rock the client draws, at the
// mesh's resolution: the detail level's 0.25-0.3 m spacing holds the metre-scale rock and the
// speleothems a vertex lands on, not the thinnest straws or the 15 cm octave, which only the
// GPU's tessellation (or relief.hpp evaluated where needed) resolves.
#pragma once

#include "cave/layout.hpp"
#include "mesh/room_mesh.hpp"

namespace grotto::tools {

struct BakeStats {
  size_t moved = 0;        // vertices displaced (all but the rims')
  double largest = 0;      // the largest displacement, metres
  double largest_hang = 0; // the largest vertical speleothem offset, metres
};

// Displaces `mesh` (of `room`) by the relief at full strength and replaces its normals by the
// displaced surface's. Rim vertices stay bit for bit (the relief is zero on a rim, so the seams
// between rooms stay closed); the relief fades in over `rim_fade` metres from the nearest rim
// vertex, as the GPU's fades over a patch triangle.
BakeStats bake_relief(mesh::RoomMesh& mesh, const cave::Room& room, double rim_fade = 0.56);

}  // namespace grotto::tools
