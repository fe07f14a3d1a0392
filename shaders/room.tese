// Room tessellation evaluation shader: PN triangles (Vlachos et al. 2001) or Phong tessellation
// (Boubekeur & Alexa 2008) over the patch, then the rock's relief (shaders/relief.glsl: warped fBm
// and ridged rock steered by the roughness channel and flowstone on walls, along the normal).
// Normals after displacement come from the relief's analytic gradients (relief_normal).
//
// Watertightness: a vertex on a patch edge is evaluated from that edge's two endpoints only, in a
// canonical order (the lexicographically smaller position first), with `precise` arithmetic, so
// the two patches that share the edge compute it with the same operations on the same operands
// and produce the same bits. Rim vertices (shared with the neighbouring room, whose roughness may
// differ) are not displaced, so seams across rooms stay closed too.
#version 410 core

layout(triangles, fractional_even_spacing, ccw) in;

in vec3 c_position[];
in vec3 c_normal[];
in float c_roughness[];
in float c_mineral[];
in float c_rim[];

out vec3 t_position;  // anchor-relative world position after displacement
out vec3 t_normal;    // after the relief
out float t_mineral;
out float t_cavity;   // relief.glsl's Relief::cavity (0.5 without relief)
out float t_spike;    // relief.glsl's Relief::spike
out float t_occlusion;  // relief.glsl's Relief::occlusion (1 without relief)
out vec3 t_warp;        // Relief::warp, Relief::rock and the step the relief was sampled at:
out float t_rock;       // room.frag adds the rock's octaves the mesh could not carry
out float t_spacing;    // (relief_rock_detail)
out vec3 t_haze;        // the lit haze between the eye and this vertex (lights.glsl), linear
out vec4 t_dripstone;   // a formation's colour and wetness (formation.vert); the rock: none

uniform mat4 u_view_proj;      // anchor-relative world to clip space
uniform ivec3 u_block;         // the anchor in world space: u_block * kReliefBlock (relief.glsl)
uniform int u_surface;         // 0 flat, 1 PN triangles, 2 Phong tessellation
uniform float u_phong_alpha;   // Phong tessellation shape factor (0.75 in the paper)
uniform float u_displacement;  // relief strength: 1 the designed relief, 0 none
// With lod.glsl's uniforms, what it takes to know the step the relief is sampled at:
uniform float u_patch_edge;    // the room's median patch edge, metres (0: sample exactly)
uniform vec3 u_camera;         // anchor-relative

#pragma grotto_include "relief.glsl"
#pragma grotto_include "lod.glsl"
#pragma grotto_include "lights.glsl"

// ---- surfaces ----

// A point of the patch's surface before displacement, with its attributes.
struct Sample {
  vec3 position;
  vec3 normal;
  float roughness;
  float mineral;
  float rim;
};

// The cubic PN edge control point next to `a` on edge a-b (relief_pn_control, kept `precise`
// here: edge points must come out with the same bits from both patches).
vec3 pn_edge_control(vec3 a, vec3 na, vec3 b) {
  precise vec3 r = (2.0 * a + b - dot(b - a, na) * na) * (1.0 / 3.0);
  return r;
}

vec3 project_to_plane(vec3 q, vec3 p, vec3 n) {
  precise vec3 r = q - dot(q - p, n) * n;
  return r;
}

// A point on edge a-b with weights wa + wb = 1, from the edge's data alone. Callers pass the
// endpoints in canonical order.
Sample edge_sample(vec3 pa, vec3 na, float ra, float ma, float rima, vec3 pb, vec3 nb, float rb,
                   float mb, float rimb, float wa, float wb) {
  Sample s;
  precise vec3 flat_p = pa * wa + pb * wb;
  precise vec3 p = flat_p;
  if (u_surface == 1) {
    vec3 cab = pn_edge_control(pa, na, pb);
    vec3 cba = pn_edge_control(pb, nb, pa);
    p = pa * (wa * wa * wa) + pb * (wb * wb * wb) + cab * (3.0 * wa * wa * wb) +
        cba * (3.0 * wa * wb * wb);
  } else if (u_surface == 2) {
    precise vec3 q = project_to_plane(flat_p, pa, na) * wa + project_to_plane(flat_p, pb, nb) * wb;
    p = mix(flat_p, q, u_phong_alpha);
  }
  s.position = p;
  precise vec3 n = na * wa + nb * wb;
  s.normal = normalize(n);
  precise float r = ra * wa + rb * wb;
  precise float m = ma * wa + mb * wb;
  precise float rim = rima * wa + rimb * wb;
  s.roughness = r;
  s.mineral = m;
  s.rim = rim;
  return s;
}

bool before(vec3 a, vec3 b) {
  if (a.x != b.x) return a.x < b.x;
  if (a.y != b.y) return a.y < b.y;
  return a.z < b.z;
}

Sample edge_of(int ia, int ib, float wa, float wb) {
  if (before(c_position[ib], c_position[ia])) {
    int t = ia;
    ia = ib;
    ib = t;
    float w = wa;
    wa = wb;
    wb = w;
  }
  return edge_sample(c_position[ia], c_normal[ia], c_roughness[ia], c_mineral[ia], c_rim[ia],
                     c_position[ib], c_normal[ib], c_roughness[ib], c_mineral[ib], c_rim[ib], wa,
                     wb);
}

Sample interior(vec3 w) {
  vec3 p0 = c_position[0], p1 = c_position[1], p2 = c_position[2];
  vec3 n0 = c_normal[0], n1 = c_normal[1], n2 = c_normal[2];
  Sample s;
  vec3 flat_p = p0 * w.x + p1 * w.y + p2 * w.z;
  vec3 p = flat_p;
  if (u_surface == 1) {
    p = relief_pn_point(p0, p1, p2, n0, n1, n2, w);
  } else if (u_surface == 2) {
    vec3 q = project_to_plane(flat_p, p0, n0) * w.x + project_to_plane(flat_p, p1, n1) * w.y +
             project_to_plane(flat_p, p2, n2) * w.z;
    p = mix(flat_p, q, u_phong_alpha);
  }
  s.position = p;
  s.normal = normalize(n0 * w.x + n1 * w.y + n2 * w.z);
  s.roughness = dot(vec3(c_roughness[0], c_roughness[1], c_roughness[2]), w);
  s.mineral = dot(vec3(c_mineral[0], c_mineral[1], c_mineral[2]), w);
  s.rim = dot(vec3(c_rim[0], c_rim[1], c_rim[2]), w);
  return s;
}

// The tessellation's step near anchor-relative point p: the room's median patch edge over the level
// room.tesc gives an edge there (the silhouette heuristic's full level, its finest), so the
// relief draws no octave finer than the mesh can carry (relief_at_sampled). A
// function of the point and uniforms alone: the patches that share a vertex give it the same
// step, and the same displacement.
float sample_spacing(vec3 p) {
  if (!(u_patch_edge > 0.0)) return 0.0;
  precise vec3 d = p - u_camera;
  precise float dist = sqrt(dot(d, d));
  float level = u_lod == 1 ? tess_screen_level(u_patch_edge, max(dist, 1e-3))
                           : tess_distance_level(dist);
  return u_patch_edge / level;
}

void main() {
  vec3 w = gl_TessCoord;
  Sample s;
  // Outer edge i lies where coordinate i is zero.
  if (w.x == 0.0)
    s = edge_of(1, 2, w.y, w.z);
  else if (w.y == 0.0)
    s = edge_of(2, 0, w.z, w.x);
  else if (w.z == 0.0)
    s = edge_of(0, 1, w.x, w.y);
  else
    s = interior(w);

  ReliefPos world = relief_pos(u_block, s.position);  // the anchor is a block's corner
  float spacing = sample_spacing(s.position);
  Relief r = relief_at_sampled(world, s.normal, s.roughness, s.rim, u_displacement, spacing);
  // Rock and flowstone along the normal (relief_displace); the formations are instances of
  // their own (formation.vert).
  precise vec3 displaced = s.position + s.normal * r.height;
  t_position = displaced;
  t_normal = relief_normal(s.normal, r.gradient);
  t_mineral = s.mineral;
  t_cavity = r.cavity;
  t_spike = r.spike;
  t_occlusion = r.occlusion;
  t_warp = r.warp;
  t_rock = r.rock;
  t_spacing = spacing;
  // The haze varies over metres along the view: per tessellated vertex (a few pixels apart), not
  // per pixel, where its loop over the lights cost as much as their shading. (Per control point,
  // a metre apart, a bright halo showed the patches' facets.)
  t_haze = lights_haze(u_camera, displaced);
  t_dripstone = vec4(0.0);
  gl_Position = u_view_proj * vec4(displaced, 1.0);
}
