// Room fragment shader: triplanar procedural materials (floor, wall, ceiling, chosen by the normal),
// a lamp at the player and distance fog that is fully opaque at u_fog_end, before the far plane,
// so nothing beyond the fog distance shows (tests rely on it: the clear colour never shows
// through a closed cave).
#version 410 core

in vec3 t_position;
in vec3 t_normal;
in float t_mineral;
in float t_displacement;

out vec4 frag_color;

uniform vec3 u_camera;  // anchor-relative
uniform vec3 u_anchor;  // world position of the anchor (patterns are world-space)
uniform vec3 u_fog_color;
uniform float u_fog_start;
uniform float u_fog_end;
uniform float u_lamp_range;  // metres at which the lamp falls to about a fifth

float hash2(vec2 p) {
  uvec2 q = uvec2(ivec2(floor(p))) * uvec2(1597334673u, 3812015801u);
  uint n = (q.x ^ q.y) * 1597334673u;
  n ^= n >> 16;
  n *= 2246822519u;
  n ^= n >> 13;
  return float(n >> 8) * (1.0 / 16777216.0);
}

float noise2(vec2 p) {
  vec2 i = floor(p), f = p - i;
  vec2 u = f * f * (3.0 - 2.0 * f);
  float a = hash2(i), b = hash2(i + vec2(1, 0)), c = hash2(i + vec2(0, 1)),
        d = hash2(i + vec2(1, 1));
  return mix(mix(a, b, u.x), mix(c, d, u.x), u.y);
}

float pattern(vec2 p) {
  return 0.5 * noise2(p * 1.7) + 0.3 * noise2(p * 4.1) + 0.2 * noise2(p * 11.3);
}

// The three materials, each a procedural "texture" of a 2D coordinate plus the world height.
vec3 floor_material(vec2 uv) {
  float g = pattern(uv);
  return mix(vec3(0.36, 0.30, 0.22), vec3(0.55, 0.48, 0.36), g);
}
vec3 wall_material(vec2 uv, float height) {
  float strata = 0.5 + 0.5 * sin(height * 2.3 + 2.0 * noise2(uv * 0.7));
  float g = pattern(uv * 0.8);
  return mix(vec3(0.34, 0.32, 0.30), vec3(0.52, 0.45, 0.38), 0.6 * strata + 0.4 * g);
}
vec3 ceiling_material(vec2 uv) {
  float g = pattern(uv * 1.3);
  return mix(vec3(0.27, 0.27, 0.29), vec3(0.42, 0.42, 0.45), g);
}

vec3 triplanar(vec3 p, vec3 n, float t_floor, float t_ceiling) {
  vec3 w = pow(abs(n), vec3(4.0));
  w /= (w.x + w.y + w.z);
  vec2 uv_x = p.zy, uv_y = p.xz, uv_z = p.xy;
  vec3 fl = floor_material(uv_x) * w.x + floor_material(uv_y) * w.y + floor_material(uv_z) * w.z;
  vec3 wa = wall_material(uv_x, p.y) * w.x + wall_material(uv_y, p.y) * w.y +
            wall_material(uv_z, p.y) * w.z;
  vec3 ce =
      ceiling_material(uv_x) * w.x + ceiling_material(uv_y) * w.y + ceiling_material(uv_z) * w.z;
  return wa * (1.0 - t_floor - t_ceiling) + fl * t_floor + ce * t_ceiling;
}

void main() {
  vec3 n = normalize(t_normal);
  vec3 to_eye = u_camera - t_position;
  float dist = length(to_eye);
  vec3 l = to_eye / max(dist, 1e-4);
  // Cave meshes face inward, but a thin wall can be seen from behind: light both sides.
  if (dot(n, l) < 0.0) n = -n;

  vec3 world = t_position + u_anchor;
  float t_floor = smoothstep(0.45, 0.8, n.y);
  float t_ceiling = smoothstep(0.45, 0.8, -n.y);
  vec3 albedo = triplanar(world, n, t_floor, t_ceiling);
  // Minerals tint the rock; displaced tips are lighter (thesis §5.5's stalactite tips).
  albedo = mix(albedo, vec3(0.45, 0.52, 0.58), 0.35 * t_mineral);
  albedo *= 1.0 + clamp(t_displacement * 1.5, -0.2, 0.35);

  float lambert = max(dot(n, l), 0.0);
  float attenuation = 1.0 / (1.0 + 4.0 * (dist / u_lamp_range) * (dist / u_lamp_range));
  vec3 h = l;  // the lamp is at the eye: the half vector is the view vector
  float specular = pow(max(dot(n, h), 0.0), 32.0) * 0.15 * (0.5 + t_floor);
  vec3 lamp = vec3(1.0, 0.92, 0.8);
  vec3 color = albedo * (0.06 + 1.1 * lambert * attenuation * lamp) + specular * attenuation * lamp;

  float fog = smoothstep(u_fog_start, u_fog_end, dist);
  frag_color = vec4(mix(color, u_fog_color, fog), 1.0);
}
