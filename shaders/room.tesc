// Room tessellation control shader: one level per edge, computed from that edge's two endpoints
// alone and symmetric in them, so the two patches sharing an edge (in one room or across a portal
// seam) pick the same level and the same vertices (thesis §5.2.1: no tearing). Three heuristics
// (u_lod, renderer.hpp's LodHeuristic):
//   0 distance:     the thesis's MaxTess * cos(D / MaxDist * pi/2), D from the camera to the edge's
//                   midpoint;
//   1 screen space: the edge's bounding sphere (centre its midpoint, diameter its length) projected
//                   at its centre's distance, over u_target_pixels pixels per segment;
//   2 silhouette:   Dyken et al.'s silhouette refinement: half the distance level, except on edges
//                   whose endpoint normals straddle the view direction (one endpoint faces the
//                   camera, the other faces away), which keep the full level.
// Each is built from commutative operations on the endpoints (a + b, |a - b|, a product of the two
// endpoints' signs) under `precise`, so swapping the endpoints gives the same bits.
//
// Patch culling (u_patch_culling): a patch gets outer levels 0, which discards it, only when it is
// provably invisible: entirely outside one frustum plane, or facing away from the camera, by more
// than the distance the tessellated, displaced surface can stray from the flat triangle.
#version 410 core

layout(vertices = 3) out;

in vec3 v_position[];
in vec3 v_normal[];
in float v_roughness[];
in float v_mineral[];
in float v_rim[];

out vec3 c_position[];
out vec3 c_normal[];
out float c_roughness[];
out float c_mineral[];
out float c_rim[];

uniform vec3 u_camera;           // anchor-relative
uniform bool u_patch_culling;    // discard patches that are provably invisible
uniform vec4 u_frustum[6];       // unit-normal planes (anchor-relative), inside positive
uniform int u_surface;           // 0 flat, 1 PN triangles, 2 Phong tessellation (room.tese)
uniform float u_relief_margin;   // metres the relief can move the surface (relief_bound)

#pragma grotto_include "lod.glsl"

float distance_level(vec3 a, vec3 b) {
  // a + b is commutative bit for bit; `precise` keeps the compiler from contracting or
  // reassociating differently where the function is inlined for different edges.
  precise vec3 mid = (a + b) * 0.5;
  precise vec3 d = mid - u_camera;
  precise float dist = sqrt(dot(d, d));
  return tess_distance_level(dist);
}

float screen_space_level(vec3 a, vec3 b) {
  precise vec3 mid = (a + b) * 0.5;
  precise vec3 d = mid - u_camera;
  precise vec3 e = a - b;  // b - a is its exact negation: the same length
  precise float dist = max(sqrt(dot(d, d)), 1e-3);
  precise float len = sqrt(dot(e, e));
  return tess_screen_level(len, dist);
}

float silhouette_level(vec3 a, vec3 na, vec3 b, vec3 nb) {
  precise float sa = dot(na, u_camera - a);
  precise float sb = dot(nb, u_camera - b);
  float level = distance_level(a, b);
  return sa * sb <= 0.0 ? level : max(1.0, 0.5 * level);
}

float edge_level(int i, int j) {
  if (u_lod == 1) return screen_space_level(v_position[i], v_position[j]);
  if (u_lod == 2)
    return silhouette_level(v_position[i], v_normal[i], v_position[j], v_normal[j]);
  return distance_level(v_position[i], v_position[j]);
}

// How far the final surface can lie from the flat triangle p0 p1 p2. PN triangles: every Bezier
// control point is within a third of an edge (edge points) or half the longest edge (the centre)
// of the flat triangle, and the patch lies in their convex hull. Phong tessellation: a projection
// onto a vertex's tangent plane moves a point by at most its distance to that vertex, at most the
// longest edge. The relief: relief.glsl's relief_bound (the rock and flowstone along the normal;
// the formations are instances of their own, culled apart: renderer.cpp).
float surface_margin(vec3 p0, vec3 p1, vec3 p2) {
  vec3 e0 = p1 - p0, e1 = p2 - p1, e2 = p0 - p2;
  float longest = sqrt(max(dot(e0, e0), max(dot(e1, e1), dot(e2, e2))));
  return (u_surface == 0 ? 0.0 : longest) + u_relief_margin + 0.01;
}

bool outside_frustum(vec3 p0, vec3 p1, vec3 p2, float margin) {
  for (int k = 0; k < 6; ++k) {
    vec4 plane = u_frustum[k];  // unit normals
    if (dot(plane.xyz, p0) + plane.w < -margin && dot(plane.xyz, p1) + plane.w < -margin &&
        dot(plane.xyz, p2) + plane.w < -margin)
      return true;
  }
  return false;
}

// Back-facing test. Triangles are counter-clockwise seen from inside the cave, so the face normal
// and the vertex normals point into the cave. The whole surface lies within `margin` of the
// triangle's plane, so a camera further than that behind the plane sees the patch from the rock
// side, and the cave being closed (fog caps close unloaded portals), something facing it lies in
// front. That alone is not enough: at a ridge the neighbour faces the camera, and displacement
// bumps (noise slopes reach ~80 degrees) or PN bulges on this patch can rise above the ridge line
// and be seen past it (measured: a few pixels per frame). So the camera must also be more than
// `margin` behind every vertex's tangent plane: vertex normals average the faces around the
// vertex, so no ridge that faces the camera meets the patch. A degenerate triangle gives NaN, and
// NaN comparisons never cull.
// The relief's bumps reach ~80 degrees of slope: a camera just behind the base plane can see the
// side of one at a grazing angle, so the back-facing test asks for kBackMargins margins (3: with
// 2, a hall's bed steps and notches let a pixel of a culled patch show past a ridge).
const float kBackMargins = 3.0;
bool facing_away(vec3 p0, vec3 p1, vec3 p2, float margin) {
  vec3 n = normalize(cross(p1 - p0, p2 - p0));
  if (!(dot(u_camera - p0, n) < -margin)) return false;
  for (int i = 0; i < 3; ++i)
    if (!(dot(u_camera - v_position[i], normalize(v_normal[i])) < -margin)) return false;
  return true;
}

void main() {
  c_position[gl_InvocationID] = v_position[gl_InvocationID];
  c_normal[gl_InvocationID] = v_normal[gl_InvocationID];
  c_roughness[gl_InvocationID] = v_roughness[gl_InvocationID];
  c_mineral[gl_InvocationID] = v_mineral[gl_InvocationID];
  c_rim[gl_InvocationID] = v_rim[gl_InvocationID];
  if (gl_InvocationID == 0) {
    vec3 p0 = v_position[0], p1 = v_position[1], p2 = v_position[2];
    if (u_patch_culling) {
      float margin = surface_margin(p0, p1, p2);
      if (outside_frustum(p0, p1, p2, margin) || facing_away(p0, p1, p2, kBackMargins * margin)) {
        gl_TessLevelOuter[0] = 0.0;
        gl_TessLevelOuter[1] = 0.0;
        gl_TessLevelOuter[2] = 0.0;
        gl_TessLevelInner[0] = 0.0;
        return;
      }
    }
    // Outer level i belongs to the edge opposite vertex i (GL 4.5 §11.2.2.1).
    float e0 = edge_level(1, 2);
    float e1 = edge_level(2, 0);
    float e2 = edge_level(0, 1);
    gl_TessLevelOuter[0] = e0;
    gl_TessLevelOuter[1] = e1;
    gl_TessLevelOuter[2] = e2;
    gl_TessLevelInner[0] = max(e0, max(e1, e2));
  }
}
