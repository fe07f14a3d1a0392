// Room tessellation evaluation shader: PN triangles (Vlachos et al. 2001) or Phong tessellation
// (Boubekeur & Alexa 2008) over the patch, then displacement along the normal by world-space
// noise, its amplitude steered by the roughness channel and biased to undersides (thesis §5.5:
// stalactites). Normals after displacement come from the noise's analytic gradient.
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
out vec3 t_normal;
out float t_mineral;
out float t_displacement;  // metres along the normal, for the tint

uniform mat4 u_view_proj;      // anchor-relative world to clip space
uniform vec3 u_anchor;         // the anchor in world space (noise is world-space)
uniform int u_surface;         // 0 flat, 1 PN triangles, 2 Phong tessellation
uniform float u_phong_alpha;   // Phong tessellation shape factor (0.75 in the paper)
uniform float u_displacement;  // metres at roughness 1 on a ceiling; 0 turns displacement off
uniform float u_noise_scale;   // noise frequency, 1/metres

// ---- noise: 3D value noise with analytic derivatives (quintic fade) ----

float hash(ivec3 c) {
  uvec3 q = uvec3(c) * uvec3(1597334673u, 3812015801u, 2798796415u);
  uint n = (q.x ^ q.y ^ q.z) * 1597334673u;
  n ^= n >> 16;
  n *= 2246822519u;
  n ^= n >> 13;
  return float(n >> 8) * (1.0 / 16777216.0);
}

// .x value in [-1, 1], .yzw its gradient.
vec4 value_noise(vec3 x) {
  vec3 cell = floor(x);
  ivec3 i = ivec3(cell);
  vec3 f = x - cell;
  vec3 u = f * f * f * (f * (f * 6.0 - 15.0) + 10.0);
  vec3 du = 30.0 * f * f * (f * (f - 2.0) + 1.0);
  float a = hash(i + ivec3(0, 0, 0));
  float b = hash(i + ivec3(1, 0, 0));
  float c = hash(i + ivec3(0, 1, 0));
  float d = hash(i + ivec3(1, 1, 0));
  float e = hash(i + ivec3(0, 0, 1));
  float g = hash(i + ivec3(1, 0, 1));
  float h = hash(i + ivec3(0, 1, 1));
  float k = hash(i + ivec3(1, 1, 1));
  float k0 = a, k1 = b - a, k2 = c - a, k3 = e - a, k4 = a - b - c + d, k5 = a - c - e + h,
        k6 = a - b - e + g, k7 = -a + b + c - d + e - g - h + k;
  float v = k0 + k1 * u.x + k2 * u.y + k3 * u.z + k4 * u.x * u.y + k5 * u.y * u.z +
            k6 * u.z * u.x + k7 * u.x * u.y * u.z;
  vec3 dv = du * vec3(k1 + k4 * u.y + k6 * u.z + k7 * u.y * u.z,
                      k2 + k5 * u.z + k4 * u.x + k7 * u.z * u.x,
                      k3 + k6 * u.x + k5 * u.y + k7 * u.x * u.y);
  return vec4(2.0 * v - 1.0, 2.0 * dv);
}

// Three octaves; .x value, .yzw gradient with respect to world position.
vec4 fbm(vec3 p) {
  vec4 sum = vec4(0.0);
  float amplitude = 0.5;
  float frequency = u_noise_scale;
  for (int o = 0; o < 3; ++o) {
    vec4 n = value_noise(p * frequency);
    sum += amplitude * vec4(n.x, n.yzw * frequency);
    amplitude *= 0.5;
    frequency *= 2.03;
  }
  return sum;
}

// ---- surfaces ----

// A point of the patch's surface before displacement, with its attributes.
struct Sample {
  vec3 position;
  vec3 normal;
  float roughness;
  float mineral;
  float rim;
};

// The cubic PN edge control point next to `a` on edge a-b.
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
    vec3 b210 = pn_edge_control(p0, n0, p1), b120 = pn_edge_control(p1, n1, p0);
    vec3 b021 = pn_edge_control(p1, n1, p2), b012 = pn_edge_control(p2, n2, p1);
    vec3 b102 = pn_edge_control(p2, n2, p0), b201 = pn_edge_control(p0, n0, p2);
    vec3 e = (b210 + b120 + b021 + b012 + b102 + b201) / 6.0;
    vec3 v = (p0 + p1 + p2) / 3.0;
    vec3 b111 = e + (e - v) * 0.5;
    float u = w.x, vv = w.y, t = w.z;
    p = p0 * (u * u * u) + p1 * (vv * vv * vv) + p2 * (t * t * t) + b210 * (3.0 * u * u * vv) +
        b120 * (3.0 * u * vv * vv) + b201 * (3.0 * u * u * t) + b021 * (3.0 * vv * vv * t) +
        b102 * (3.0 * u * t * t) + b012 * (3.0 * vv * t * t) + b111 * (6.0 * u * vv * t);
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

  // Undersides (normals pointing down into the cave) grow stalactites; floors get a little.
  float underside = clamp(-s.normal.y, 0.0, 1.0);
  float amplitude =
      u_displacement * s.roughness * (1.0 - clamp(s.rim, 0.0, 1.0)) * mix(0.25, 1.0, underside);
  precise vec3 world = s.position + u_anchor;
  vec4 n = fbm(world);
  // Stalactites: on undersides only the positive lobe, sharpened.
  float shaped = mix(n.x, max(n.x, 0.0) * max(n.x, 0.0) * 2.0, underside);
  vec3 grad = mix(n.yzw, 4.0 * max(n.x, 0.0) * n.yzw, underside);
  float d = amplitude * shaped;
  precise vec3 displaced = s.position + s.normal * d;
  vec3 tangential = grad - dot(grad, s.normal) * s.normal;
  t_position = displaced;
  t_normal = normalize(s.normal - amplitude * tangential);
  t_mineral = s.mineral;
  t_displacement = d;
  gl_Position = u_view_proj * vec4(displaced, 1.0);
}
