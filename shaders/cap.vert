// Fog caps: discs over portals whose room is not loaded, so the player sees fog there rather
// than the void. Positions are anchor-relative, built on the CPU each frame.
#version 410 core

layout(location = 0) in vec3 a_position;

uniform mat4 u_view_proj;

void main() {
  gl_Position = u_view_proj * vec4(a_position, 1.0);
}
