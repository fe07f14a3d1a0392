// Formation vertex shader: one instance of a speleothem mesh. The mesh is a grid of
// rings along the axis by points round it, the same for every instance of a level of detail; the
// instance's shape (shaders/formation.glsl) places each point, so every stalactite, stalagmite,
// soda straw, column and drapery is smooth and its own. Shaded by room.frag: its outputs are room.tese's,
// a formation being calcite (t_spike: ochre at the root, cream towards the growing tip) with no
// rock detail of its own (t_rock 0); a boulder is limestone (t_spike -1: the walls' rock).
#version 410 core

layout(location = 0) in vec2 a_grid;  // (0-1 along the span from the rock to the tip, angle)
layout(location = 1) in vec4 i_root;  // anchor-relative root, length
layout(location = 2) in vec4 i_size;  // radius, tip radius, embed, kind
layout(location = 3) in vec4 i_form;  // taper, flare, rings, bulbs
layout(location = 4) in vec4 i_turn;  // seed, yaw, tint, wet

uniform mat4 u_view_proj;  // anchor-relative world to clip space

out vec3 t_position;  // anchor-relative
out vec3 t_normal;
out float t_mineral;
out float t_cavity;
out float t_spike;
out float t_occlusion;
out vec3 t_warp;
out float t_rock;
out float t_spacing;
out vec3 t_haze;
out vec4 t_dripstone;  // rgb: formation_colour of its tint (linear albedo); a: how wet it is

uniform vec3 u_camera;  // anchor-relative

#pragma grotto_include "formation.glsl"
#pragma grotto_include "relief.glsl"
#pragma grotto_include "lights.glsl"

void main() {
  FormationShape f;
  f.root = i_root.xyz;
  f.length = i_root.w;
  f.radius = i_size.x;
  f.tip = i_size.y;
  f.embed = i_size.z;
  f.kind = int(i_size.w + 0.5);
  f.taper = i_form.x;
  f.flare = i_form.y;
  f.rings = i_form.z;
  f.bulbs = i_form.w;
  f.seed = i_turn.x;
  f.yaw = i_turn.y;
  f.tint = i_turn.z;
  f.wet = i_turn.w;
  float start = formation_start(f), end = formation_end(f);
  // Rings closer together at both ends (the root's flare, the tip's curve) than along the body.
  float v = a_grid.x;
  float g = v - 0.6 * sin(6.2831853 * v) / 6.2831853;
  float s = mix(start, end, g);
  float theta = a_grid.y;
  vec3 p = formation_point(f, s, theta);
  // The normal from the surface's two tangents (central differences: the profile, rings and lobes
  // all bend it); along the axis at a tip, where the ring shrinks to a point.
  float ds = max(0.002, 0.004 * (end - start));
  vec3 along = formation_point(f, s + ds, theta) - formation_point(f, s - ds, theta);
  vec3 round = formation_point(f, s, theta + 0.02) - formation_point(f, s, theta - 0.02);
  vec3 n = cross(along, round);
  float nl = length(n);
  vec3 outward = formation_outward(f, s, theta, p);
  n = nl > 1e-9 ? n / nl : normalize(outward);
  if (dot(n, outward) < 0.0) n = -n;
  t_position = p;
  t_normal = n;
  t_mineral = 0.0;
  t_cavity = 0.6;
  t_spike = formation_age(f, s, theta);
  // The crease where the root's flare meets the rock holds a little less of the sky; a
  // boulder's foot, under its overhanging sides, less still.
  if (f.kind == kFormationDrapery)
    t_occlusion = mix(0.8, 1.0, smoothstep(-0.02, 0.1, -(p.y - f.root.y)));
  else if (f.kind == kFormationBoulder)
    t_occlusion = mix(0.6, 1.0, smoothstep(-0.02, 0.3 * min(f.length, f.radius) + 0.05,
                                           p.y - f.root.y));
  else
    t_occlusion = mix(0.8, 1.0, smoothstep(-0.02, 0.5 * (f.radius + 0.05), s));
  t_warp = vec3(0.0);
  t_rock = 0.0;
  t_spacing = 0.0;
  t_haze = lights_haze(u_camera, p);
  t_dripstone = vec4(formation_colour(f.tint), f.wet);
  gl_Position = u_view_proj * vec4(p, 1.0);
}
