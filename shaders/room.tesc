// Room tessellation control shader: one level per edge, computed from that edge's two endpoints
// alone and symmetric in them, so the two patches sharing an edge (in one room or across a portal
// seam) pick the same level and the same vertices (thesis §5.2.1: no tearing). The heuristic is
// the thesis's MaxTess * cos(D / MaxDist * pi/2), clamped to at least 1, with D the distance from
// the camera to the edge's midpoint.
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

uniform vec3 u_camera;      // anchor-relative
uniform float u_max_tess;   // MaxTess; 1 disables tessellation
uniform float u_max_dist;   // MaxDist, metres

float edge_level(vec3 a, vec3 b) {
  // a + b is commutative bit for bit; `precise` keeps the compiler from contracting or
  // reassociating differently where the function is inlined for different edges.
  precise vec3 mid = (a + b) * 0.5;
  precise vec3 d = mid - u_camera;
  precise float dist = sqrt(dot(d, d));
  float x = clamp(dist / u_max_dist, 0.0, 1.0);
  return max(1.0, u_max_tess * cos(x * 1.5707963267948966));
}

void main() {
  c_position[gl_InvocationID] = v_position[gl_InvocationID];
  c_normal[gl_InvocationID] = v_normal[gl_InvocationID];
  c_roughness[gl_InvocationID] = v_roughness[gl_InvocationID];
  c_mineral[gl_InvocationID] = v_mineral[gl_InvocationID];
  c_rim[gl_InvocationID] = v_rim[gl_InvocationID];
  if (gl_InvocationID == 0) {
    // Outer level i belongs to the edge opposite vertex i (GL 4.5 §11.2.2.1).
    float e0 = edge_level(v_position[1], v_position[2]);
    float e1 = edge_level(v_position[2], v_position[0]);
    float e2 = edge_level(v_position[0], v_position[1]);
    gl_TessLevelOuter[0] = e0;
    gl_TessLevelOuter[1] = e1;
    gl_TessLevelOuter[2] = e2;
    gl_TessLevelInner[0] = max(e0, max(e1, e2));
  }
}
