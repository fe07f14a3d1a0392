// Room fragment shader: procedural rock at world scale (no textures, so nothing mirrors, tiles or
// blurs: 3-D noise evaluated where the fragment is), lit by the player's headlamp, tone mapped.
//   material: floor (damp sediment), walls (limestone with strata of varying thickness),
//             ceiling (darker), speleothems (calcite with growth rings, ochre to cream at the
//             growing tip, a matte wet film and a little translucency; thesis §5.5's tint from
//             displacement), fine detail below the relief's 5 cm (relief.glsl's relief_fine:
//             grain, pits, joints), faded by the pixel's footprint so it never shimmers;
//   light:    a headlamp a little above and right of the eye with a beam and 1/d^2-like falloff
//             (so the relief casts shading the viewer can see), ambient occlusion from the
//             relief (Relief::occlusion: crevices, formations' feet), wet Blinn-Phong specular, a
//             faint bounce;
//   output:   ACES filmic tone mapping and gamma, then fog towards the display-space fog colour
//             (near black: the dark beyond the lamp), fully opaque at u_fog_end before the far
//             plane, so the clear colour never shows through a closed cave (tests rely on it).
//             Alpha is the glow mask of emissive minerals, read by the bloom pass (renderer.cpp).
#version 410 core

in vec3 t_position;
in vec3 t_normal;
in float t_mineral;
in float t_cavity;
in float t_spike;
in float t_occlusion;
in vec3 t_warp;
in float t_rock;
in float t_spacing;
in vec3 t_haze;
in vec4 t_dripstone;  // a formation's calcite colour and wetness (formation.vert); the rock: none  // lights.glsl's lights_haze at the vertices (room.tese, formation.vert)

layout(location = 0) out vec4 frag_color;

uniform vec3 u_camera;   // anchor-relative
uniform ivec3 u_block;   // the anchor in world space: u_block * kReliefBlock (relief.glsl)
uniform vec3 u_lamp;     // anchor-relative headlamp position
uniform vec3 u_forward;  // unit view direction: the beam's axis
uniform vec3 u_fog_color;  // display space
uniform float u_fog_start;
uniform float u_fog_end;
uniform float u_lamp_range;       // metres at which the lamp falls to about a tenth
uniform float u_fine_detail;  // relief_fine's grain, pits and joints; 0: none
uniform float u_ao;           // 1: the relief's ambient occlusion (t_occlusion); 0: none
uniform float u_pixel_scale;  // pixels per metre at 1 m along the view axis (room.tesc's too)
uniform float u_exposure;
uniform float u_glow;  // emissive minerals' strength; 0: none

#pragma grotto_include "relief.glsl"
#pragma grotto_include "lights.glsl"

vec3 aces(vec3 x) {
  // Narkowicz's fit of the ACES filmic curve.
  return clamp((x * (2.51 * x + 0.03)) / (x * (2.43 * x + 0.59) + 0.14), 0.0, 1.0);
}

void main() {
  vec3 n = normalize(t_normal);
  vec3 to_eye = u_camera - t_position;
  float dist = length(to_eye);
  vec3 v = to_eye / max(dist, 1e-4);
  // Cave meshes face inward, but a thin wall can be seen from behind: light both sides.
  if (dot(n, v) < 0.0) n = -n;
  // World-space, exact however far out (relief.glsl's ReliefPos): the anchor is a block's corner.
  ReliefPos world = relief_pos(u_block, t_position);

  // The pixel's footprint on the surface, metres: its size at this distance, stretched as the
  // surface turns away (capped at 4x). From the interpolated normal and the distance, not from
  // dFdx/dFdy of the position: those are constant over each tessellated triangle and jump from
  // one to the next, which would show the triangles through the fade.
  float footprint = dist / u_pixel_scale / max(dot(n, v), 0.25);

  // Where the surface faces: floors blend into walls into ceilings. A block fallen from the
  // ceiling (a boulder, formation.vert: t_spike -1) is the walls' limestone all over, its top
  // only dusted with the floor's sediment.
  float fallen = t_spike < -0.5 ? 1.0 : 0.0;
  float ground = smoothstep(0.35, 0.8, n.y) * (1.0 - 0.75 * fallen);
  float ceiling = smoothstep(0.35, 0.8, -n.y);
  float calcite = smoothstep(0.02, 0.2, t_spike);

  // Limestone walls: mottling at two scales, strata whose thickness wanders, bedding lines.
  vec4 m1 = relief_noise_at(world, ivec3(819), vec3(5.0, 1.0, 3.0));    // 0.8 per metre
  vec4 m2 = relief_noise_at(world, ivec3(3379), vec3(-9.0, 4.0, 2.0));  // 3.3

  // Fine detail: bare rock is grained, pitted in patches and jointed in runs; sediment grained;
  // calcite only finely grained (its wet film smooths it).
  float bare = (1.0 - ground) * (1.0 - calcite);
  ReliefFine fine = relief_fine(world, n, footprint, u_fine_detail * mix(1.0, 0.5, calcite),
                                u_fine_detail * bare * smoothstep(-0.2, 0.3, m1.x),
                                u_fine_detail * bare);
  // The rock's octaves the tessellated mesh was too coarse to carry, as shading (room.tese).
  vec3 rock = relief_rock_detail(world, t_warp, t_rock, t_spacing, footprint);
  vec3 s = relief_normal(n, fine.gradient + rock);
  float mottle = 0.5 + 0.3 * m1.x + 0.2 * m2.x;
  float strata =
      relief_noise_at(world, ivec3(72, 2662, 72), 0.35 * vec3(m1.x, m1.x, m1.x)).x;  // 0.07, 2.6
  vec3 buff = vec3(0.42, 0.34, 0.25), grey = vec3(0.30, 0.29, 0.27);
  vec3 wall = mix(grey, buff, clamp(0.5 + 0.9 * strata, 0.0, 1.0)) * (0.75 + 0.5 * mottle);

  // Sediment floors: damp brown mud with grit, wetter in the hollows.
  float grit = ground > 0.0 ? relief_fine_fade(0.05, footprint) * relief_noise_at(world, ivec3(19456), vec3(0.0)).x
                           : 0.0;
  vec3 mud = vec3(0.27, 0.21, 0.16) * (0.8 + 0.25 * mottle + 0.12 * grit);
  // Ceilings: the same rock, darker and greyer.
  vec3 roof = wall * vec3(0.62, 0.62, 0.66);
  vec3 albedo = mix(mix(wall, mud, ground), roof, ceiling);

  // Minerals stain the rock grey-blue.
  albedo = mix(albedo, vec3(0.36, 0.40, 0.44), 0.4 * t_mineral);
  // Speleothems are calcite over their whole length: ochre at the root, cream towards the tip
  // where it still grows, banded by growth rings a few centimetres apart (formations: t_rock 0).
  // Flowstone (calcite on the rock, t_rock > 0) ran down the wall: fine vertical flutes, not
  // rings (horizontal bands 3 cm apart across a sheet read as streaks).
  bool formation = !(t_rock > 0.0);
  float rings = calcite > 0.0
                    ? relief_fine_fade(0.028, footprint) *
                          relief_noise_at(world,
                                          formation ? ivec3(3072, 35840, 3072)
                                                    : ivec3(20480, 2048, 20480),
                                          vec3(0.0)).x
                    : 0.0;
  float age = t_spike, stain = 0.0, ochre = 0.0;
  if (t_spike > 1.0) {
    // A drapery (formation_age: 1 + the share u of its drop), a "bacon" curtain: the layers
    // its lower edge laid down, as bands along that edge. Thin dark iron-stained lines, a few
    // millimetres to centimetres wide and unevenly spaced (where three waves of different lengths
    // crest together), in broad zones of tan and clean calcite, all wandering with the mottling;
    // their contrast fades where a pixel covers a line (no shimmer far off).
    float u = t_spike - 1.0;
    float zone = sin(u * 19.0 + 2.0 * m1.x + 0.4);
    float b = 0.45 * sin(u * 53.0 + 4.0 * m1.x) + 0.35 * sin(u * 97.0 + 3.0 * m2.x + 1.3) +
              0.3 * zone;
    float keep = relief_fine_fade(0.03, footprint);
    stain = keep * smoothstep(0.4, 0.8, b) + (1.0 - keep) * 0.18;
    ochre = smoothstep(-0.2, 0.7, zone);
    age = 0.9 - 0.3 * ochre + 0.1 * u;
  }
  // A formation's own colour (its minerals: white to orange, brown or grey), darker and ochre at
  // its root; flowstone on the rock is cream.
  vec3 tip = formation ? t_dripstone.rgb : vec3(0.78, 0.74, 0.66);
  vec3 dripstone =
      mix(tip * vec3(0.72, 0.64, 0.55), tip, smoothstep(0.2, 1.0, age)) * (0.9 + 0.1 * rings);
  dripstone = mix(dripstone, vec3(0.66, 0.44, 0.24), 0.6 * ochre);
  dripstone = mix(dripstone, vec3(0.34, 0.16, 0.07), 0.85 * stain);
  albedo = mix(albedo, dripstone, 0.9 * calcite);
  // Calcite veins where the rock is rich in minerals (not in the floors' sediment): the traces of
  // two sets of steep joints (fractures 2-3 m apart that water filled), long and nearly straight
  // across a wall, in runs with bare rock between, the second set thinner and rarer; pale in the
  // light, and faintly glowing.
  // Their six noises only where veins can be (most of the rock has none). Not on ceilings: seen
  // from below at a grazing angle their straight traces read as scratches across the roof.
  float veins =
      smoothstep(0.55, 0.85, t_mineral) * (1.0 - calcite) * (1.0 - ground) * (1.0 - ceiling);
  if (veins > 0.0) {
    veins *= max(smoothstep(0.05, 0.4, relief_noise_at(world, ivec3(307), vec3(0.0, 0.0, 29.0)).x) *
                     vein_trace(world, vec3(0.87, 0.12, 0.48), 2.3, 0.0, 0.03, footprint),
                 smoothstep(0.2, 0.5, relief_noise_at(world, ivec3(256), vec3(7.0, 0.0, 3.0)).x) *
                     vein_trace(world, vec3(-0.47, 0.1, 0.88), 3.1, 0.4, 0.015, footprint));
  }
  albedo = mix(albedo, vec3(0.72, 0.70, 0.64), 0.8 * veins);
  albedo *= fine.tint * fine.cavity;

  // Wetness: floors' hollows and running flowstone (glossier), speleothems (a thin water film
  // on calcite: a broad, faint sheen, not a plastic highlight).
  float wet = clamp(0.55 * ground * (1.0 - t_cavity) + 0.25 * smoothstep(0.2, 0.8, m1.x), 0.0, 1.0);
  albedo *= 1.0 - 0.3 * wet * ground;
  // An active formation's water film darkens its calcite and gives it a sharp highlight; a dry
  // one is matte.
  float film = formation ? t_dripstone.a * calcite : 0.0;
  albedo *= 1.0 - 0.25 * film;
  float occlusion = mix(1.0, t_occlusion, u_ao);

  // The headlamp.
  vec3 to_lamp = u_lamp - t_position;
  float lamp_dist = length(to_lamp);
  vec3 l = to_lamp / max(lamp_dist, 1e-4);
  float k = lamp_dist / (0.3 * u_lamp_range);
  float attenuation = 1.0 / (1.0 + k * k);
  float beam = mix(0.3, 1.0, smoothstep(0.72, 0.95, dot(-v, u_forward)));
  // Calcite is translucent: light wraps a little round a stalactite, and a drapery's sheet, a
  // few centimetres thick, lets light from behind through, amber (iron), less through its dark
  // bands: a backlit curtain glows and its bands show dark against it.
  float wrap = 0.25 * calcite;
  vec3 through = t_spike > 1.0 ? 0.35 * (1.0 - 0.8 * stain) * (1.0 - 0.3 * ochre) *
                                     vec3(1.0, 0.62, 0.3)
                               : vec3(0.0);
  float lambert = max((dot(s, l) + wrap) / (1.0 + wrap), 0.0);
  vec3 h = normalize(l + v);
  float shininess = mix(mix(12.0, 90.0, wet), mix(16.0, 140.0, film), calcite);
  float specular = pow(max(dot(s, h), 0.0), shininess) *
                   mix(mix(0.03, 0.6, wet), mix(0.07, 0.5, film), calcite) * (shininess + 8.0) /
                   25.0;
  vec3 lamp = vec3(1.0, 0.9, 0.75) * 2.0 * attenuation * beam * u_headlamp;
  vec3 color = albedo * occlusion * (lambert * lamp + vec3(0.012, 0.014, 0.018)) +
               specular * lambert * lamp * mix(0.5, 1.0, occlusion);

  // The veins' faint glow (bloom's mask).
  float glow = 0.35 * u_glow * veins;
  color += glow * vec3(0.2, 0.85, 0.7) * 0.9;
  // The world's lights and flares (lights.glsl), and the haze they light.
  float source_glow;
  color += lights_shade(t_position, world, s, v, albedo * occlusion, wrap, through, footprint,
                        source_glow);
  glow = max(glow, source_glow);
  // The haze's light, tone-mapped but not gamma-encoded before it is screened over the picture:
  // encoded, a faint veil (0.05 linear) read as a quarter of the way to white, and within a few
  // metres of a light the whole view went milky.
  vec3 haze = aces(t_haze * u_exposure);

  vec3 display = pow(aces(color * u_exposure), vec3(1.0 / 2.2));
  float fog = smoothstep(u_fog_start, u_fog_end, dist);
  frag_color = vec4(mix(display, u_fog_color, fog), glow * (1.0 - fog));
  frag_color.rgb = 1.0 - (1.0 - frag_color.rgb) * (1.0 - haze);  // lit haze in front of the fog
}
