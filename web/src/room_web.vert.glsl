// Room vertex shader for WebGL2 (the browser viewer, web/): WebGL2 has no tessellation, so the
// decode worker subdivides each room's patch mesh once (web/src/decode_core.js: PN edge midpoints,
// shared so no cracks, rim edges keeping rim weight 1) and this stage does per vertex what
// room.tese does per tessellated vertex: the same relief (relief.glsl's relief_at_sampled, along
// the normal), the same normal after relief (relief_normal), the same t_* outputs for room.frag and
// the same haze (lights.glsl's lights_haze). Written in the native dialect (GLSL 4.10 with
// grotto_include): web/tools/shaders.mjs turns it into GLSL ES 3.00 like room.frag.
#version 410 core

layout(location = 0) in vec3 a_position;  // metres from the room origin (the frame's origin)
layout(location = 1) in vec3 a_normal;    // unit, facing into the cave (PROTOCOL's Normals)
layout(location = 2) in float a_roughness;
layout(location = 3) in float a_mineral;
layout(location = 4) in float a_rim;  // 1 on a portal rim, else 0 (0.5 between)

out vec3 t_position;  // anchor-relative world position after displacement
out vec3 t_normal;    // after the relief
out float t_mineral;
out float t_cavity;
out float t_spike;
out float t_occlusion;
out vec3 t_warp;
out float t_rock;
out float t_spacing;
out vec3 t_haze;
out vec4 t_dripstone;  // a formation's colour and wetness (formation.vert); the rock: none

uniform vec3 u_room_offset;    // room origin - anchor (exact: both on the wire's 1/256 m grid)
uniform mat4 u_view_proj;      // anchor-relative world to clip space
uniform ivec3 u_block;         // the anchor in world space: u_block * kReliefBlock (relief.glsl)
uniform float u_displacement;  // relief strength: 1 the designed relief, 0 none
uniform float u_patch_edge;    // the subdivided mesh's median edge, metres: the relief's step
uniform vec3 u_camera;         // anchor-relative

#pragma grotto_include "relief.glsl"
#pragma grotto_include "lights.glsl"

void main() {
  vec3 p = a_position + u_room_offset;
  vec3 n = normalize(a_normal);
  ReliefPos world = relief_pos(u_block, p);  // the anchor is a block's corner
  // The mesh's own step, as room.tese's sample_spacing gives the tessellation's: the octaves the
  // mesh cannot carry stay out of its shape and room.frag adds them to the shading.
  float spacing = u_patch_edge;
  Relief r = relief_at_sampled(world, n, a_roughness, a_rim, u_displacement, spacing);
  vec3 displaced = relief_displace(p, n, r);
  t_position = displaced;
  t_normal = relief_normal(n, r.gradient);
  t_mineral = a_mineral;
  t_cavity = r.cavity;
  t_spike = r.spike;
  t_occlusion = r.occlusion;
  t_warp = r.warp;
  t_rock = r.rock;
  t_spacing = spacing;
  t_haze = lights_haze(u_camera, displaced);
  t_dripstone = vec4(0.0);
  gl_Position = u_view_proj * vec4(displaced, 1.0);
}
