// Room fragment shader: triplanar texturing (thesis §3.3.2) with the generated materials of
// client/render/materials.hpp, a different one for floor, walls and ceiling chosen by the normal;
// normal mapping in a tangent frame synthesized from the normal alone (§3.3.2: the tangent is the
// normal crossed with an axis, the bitangent the tangent crossed with the normal); a lamp at the
// player; and distance fog that is fully opaque at u_fog_end, before the far plane, so nothing
// beyond the fog distance shows (tests rely on it: the clear colour never shows through a closed
// cave).
#version 410 core

in vec3 t_position;
in vec3 t_normal;
in float t_mineral;
in float t_displacement;

out vec4 frag_color;

uniform vec3 u_camera;  // anchor-relative
uniform vec3 u_anchor;  // world position of the anchor (textures are world-space)
uniform vec3 u_fog_color;
uniform float u_fog_start;
uniform float u_fog_end;
uniform float u_lamp_range;        // metres at which the lamp falls to about a fifth
uniform sampler2DArray u_albedo;   // layers floor, wall, ceiling: rgb albedo, a height
uniform sampler2DArray u_normals;  // the same layers: tangent-space normal, a gloss
uniform float u_texture_scale;     // texture repeats per metre
uniform float u_normal_strength;   // 0: the mesh normal only

const float kFloor = 0.0, kWall = 1.0, kCeiling = 2.0;

// One layer projected along the three axes and blended by the weights w.
void triplanar(vec3 p, vec3 w, float layer, out vec4 albedo, out vec4 bump) {
  vec3 uv_x = vec3(p.zy * u_texture_scale, layer);
  vec3 uv_y = vec3(p.xz * u_texture_scale, layer);
  vec3 uv_z = vec3(p.xy * u_texture_scale, layer);
  albedo = texture(u_albedo, uv_x) * w.x + texture(u_albedo, uv_y) * w.y +
           texture(u_albedo, uv_z) * w.z;
  bump = texture(u_normals, uv_x) * w.x + texture(u_normals, uv_y) * w.y +
         texture(u_normals, uv_z) * w.z;
}

void main() {
  vec3 n = normalize(t_normal);
  vec3 to_eye = u_camera - t_position;
  float dist = length(to_eye);
  vec3 l = to_eye / max(dist, 1e-4);
  // Cave meshes face inward, but a thin wall can be seen from behind: light both sides.
  if (dot(n, l) < 0.0) n = -n;

  // Walls everywhere, blended into floor (normal up) or ceiling (normal down): two layers at most.
  vec3 world = t_position + u_anchor;
  vec3 w = pow(abs(n), vec3(4.0));
  w /= (w.x + w.y + w.z);
  float t_other = smoothstep(0.45, 0.8, abs(n.y));
  vec4 albedo, bump;
  triplanar(world, w, kWall, albedo, bump);
  if (t_other > 0.0) {
    vec4 other_albedo, other_bump;
    triplanar(world, w, n.y > 0.0 ? kFloor : kCeiling, other_albedo, other_bump);
    albedo = mix(albedo, other_albedo, t_other);
    bump = mix(bump, other_bump, t_other);
  }

  // The synthesized tangent frame; the axis switches to z where the normal is close to x.
  vec3 axis = abs(n.x) < 0.9 ? vec3(1.0, 0.0, 0.0) : vec3(0.0, 0.0, 1.0);
  vec3 tangent = normalize(cross(n, axis));
  vec3 bitangent = cross(tangent, n);
  vec3 ts = bump.xyz * 2.0 - 1.0;
  ts.xy *= u_normal_strength;
  vec3 shading = normalize(tangent * ts.x + bitangent * ts.y + n * max(ts.z, 1e-3));

  // Minerals tint the rock; displaced tips are lighter and shinier (thesis §5.5's stalactites).
  vec3 color_albedo = mix(albedo.rgb, vec3(0.45, 0.52, 0.58), 0.35 * t_mineral);
  float tip = clamp(t_displacement * 1.5, -0.2, 0.35);
  color_albedo *= 1.0 + tip;
  float gloss = clamp(bump.a + 1.5 * max(tip, 0.0), 0.0, 1.0);

  float lambert = max(dot(shading, l), 0.0);
  float attenuation = 1.0 / (1.0 + 4.0 * (dist / u_lamp_range) * (dist / u_lamp_range));
  // The lamp is at the eye: the half vector is the view vector.
  float specular = pow(max(dot(shading, l), 0.0), 8.0 + 56.0 * gloss) * (0.04 + 0.4 * gloss);
  vec3 lamp = vec3(1.0, 0.92, 0.8);
  vec3 color = color_albedo * (0.07 + 1.15 * lambert * attenuation * lamp) +
               specular * attenuation * lamp;

  float fog = smoothstep(u_fog_start, u_fog_end, dist);
  frag_color = vec4(mix(color, u_fog_color, fog), 1.0);
}
