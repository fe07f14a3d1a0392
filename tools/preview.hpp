// A software preview of room meshes: an orthographic, z-buffered, lit picture written as PNG, so a
// world can be looked at on a machine with no GPU or display (grotto-layout --png).
#pragma once

#include <string>
#include <vector>

#include "common/core/result.hpp"
#include "common/mesh/room_mesh.hpp"
#include "common/png/png.hpp"  // write_png, which grotto-layout --png uses with this preview

namespace grotto::tools {

struct PreviewOptions {
  int width = 1200;
  int height = 800;
  Vec3 view_direction{0.55, -0.75, 0.40};  // from the camera into the scene
};

// Renders every mesh seen from outside along view_direction, fitted to the image. Surfaces are
// lit from both sides (the meshes face the inside of the cave) and tinted by height and by the
// mineral channel.
std::vector<unsigned char> render_preview(const std::vector<mesh::RoomMesh>& meshes,
                                          const PreviewOptions& options);

}  // namespace grotto::tools
