// Room vertex shader: moves a control point from its room's frame into the frame of the render
// anchor (a point near the camera on a coarse power-of-two grid, renderer.cpp). Positions are
// exact grid values and so is u_room_offset, so the sum is exact in float32 and a rim vertex two
// rooms share lands on the same bits in both (core/grid.hpp).
#version 410 core

layout(location = 0) in vec3 a_position;  // metres from the room origin
layout(location = 1) in vec3 a_normal;    // unit, facing into the cave
layout(location = 2) in float a_roughness;
layout(location = 3) in float a_mineral;
layout(location = 4) in float a_rim;  // 1 on a portal rim, else 0

uniform vec3 u_room_offset;  // room origin - anchor

out vec3 v_position;
out vec3 v_normal;
out float v_roughness;
out float v_mineral;
out float v_rim;

void main() {
  precise vec3 p = a_position + u_room_offset;
  v_position = p;
  v_normal = a_normal;
  v_roughness = a_roughness;
  v_mineral = a_mineral;
  v_rim = a_rim;
}
