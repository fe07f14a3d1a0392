// Light in the dark (issue 27, item 4), spliced into room.frag: the world's lights (cave/lights.hpp:
// glow-worm colonies, glowing mineral seams, crystal clusters) and the player's flares as point
// lights with falloff, the glowing rock around each source, and the haze they light along the
// view ray. The renderer fills the arrays from render::frame_lights (the same list
// grotto-client --screenshot --json reports), the nearest GROTTO_MAX_LIGHTS at most.
//
// Falloff (cave/lights.hpp's convention): colour x intensity / (1 + d^2), windowed to zero at the
// light's range by (1 - (d / range)^4)^2 (Karis 2013, "Real Shading in Unreal Engine 4"); the
// 1 in 1 + d^2 keeps a source's own rock from going infinite. A glow-worm colony is an area of
// pinpricks `size` metres across: size^2 + d^2, no hot centre.
// Rock casts no shadows here, so a light stays in its room: it lights only what lies within its
// bound (its room's sphere, a little grown for the relief), not the next room through the rock.
// Haze: single scattering in a thin medium round each source, the in-scattered light along the
// view ray in closed form (after Sun et al. 2005, "A Practical Analytic Single Scattering Model
// for Real Time Rendering", without extinction). The kernel is 1 / (1 + d^2)^2 rather than the
// surface's 1 / (1 + d^2): a halo of a few metres round a source instead of a veil over the
// whole hall (the dark between lights is what gives a hall its depth).
#define GROTTO_MAX_LIGHTS 16
#define GLOW_WORMS 0
#define GLOW_SEAM 1
#define GLOW_CRYSTALS 2
#define GLOW_FLARE 3

uniform int u_light_count;                         // lights that can reach this room
uniform int u_light_index[GROTTO_MAX_LIGHTS];      // which of the arrays' lights they are
uniform vec4 u_light_position[GROTTO_MAX_LIGHTS];  // xyz anchor-relative; w: range (m)
uniform vec4 u_light_color[GROTTO_MAX_LIGHTS];     // rgb: linear colour x intensity at 1 m
uniform vec4 u_light_glow[GROTTO_MAX_LIGHTS];      // x: glowing patch radius (m); y: GLOW_*
uniform vec4 u_light_bound[GROTTO_MAX_LIGHTS];     // xyz anchor-relative centre; w: radius, 0: none
uniform float u_headlamp;                          // 1: the headlamp is on; 0: off
uniform float u_haze;                              // scattering per metre of the lit haze

// soft: 1 for a point source; a glow-worm colony's size (an area of pinpricks, no hot centre).
float light_falloff(float d, float range, float soft) {
  float x = d / range;
  float window = clamp(1.0 - x * x * x * x, 0.0, 1.0);
  return window * window / (soft * soft + d * d);
}

// What the lights add to a surface point p (anchor-relative; `world` the same point in world
// space) with shading normal s, unit vector v towards the eye and albedo (occlusion applied).
// wrap: translucency (calcite lets light wrap round). glow: the emissive mask for bloom.
vec3 lights_shade(vec3 p, vec3 world, vec3 s, vec3 v, vec3 albedo, float wrap, out float glow) {
  vec3 sum = vec3(0.0);
  glow = 0.0;
  for (int k = 0; k < u_light_count; ++k) {
    int i = u_light_index[k];
    vec3 to_light = u_light_position[i].xyz - p;
    float d = length(to_light);
    float range = u_light_position[i].w;
    if (d >= range) continue;
    float bound = u_light_bound[i].w;
    float inside = bound > 0.0 ? 1.0 - smoothstep(0.9 * bound, bound,
                                                  length(p - u_light_bound[i].xyz))
                               : 1.0;
    if (inside <= 0.0) continue;
    vec3 l = to_light / max(d, 1e-4);
    int kind = int(u_light_glow[i].y + 0.5);
    float soft = kind == GLOW_WORMS ? max(u_light_glow[i].x, 1.0) : 1.0;
    vec3 radiance = u_light_color[i].rgb * (light_falloff(d, range, soft) * inside);
    float lambert = max((dot(s, l) + wrap) / (1.0 + wrap), 0.0);
    vec3 h = normalize(l + v);
    float sheen = pow(max(dot(s, h), 0.0), 24.0) * 0.08;
    sum += radiance * (albedo * lambert + sheen * lambert);

    // The source itself: its rock glows within `size` metres, in a pattern of its kind.
    float size = u_light_glow[i].x;
    if (d < size) {
      float near = 1.0 - smoothstep(0.2 * size, size, d);
      float pattern;
      if (kind == GLOW_WORMS) {
        // Thousands of tiny lights: sparse dots a couple of centimetres across.
        pattern = smoothstep(0.55, 0.8, relief_noise(world * 14.0 + vec3(3.0, 0.0, 1.0)).x);
      } else if (kind == GLOW_SEAM) {
        // A vein: a thin ridge of low-frequency noise.
        pattern = smoothstep(0.9, 0.98, 1.0 - abs(relief_noise(world * 1.1 + vec3(0.0, 7.0, 0.0)).x));
      } else if (kind == GLOW_CRYSTALS) {
        // Facets: cells of noise that catch and hold the light.
        pattern = smoothstep(0.25, 0.6, relief_noise(world * 4.0 + vec3(0.0, 0.0, 11.0)).x);
      } else {
        pattern = 1.0;  // a flare: its own spot of rock is white hot
      }
      vec3 tint = u_light_color[i].rgb / max(max(u_light_color[i].r, u_light_color[i].g),
                                             max(u_light_color[i].b, 1e-4));
      float strength = kind == GLOW_FLARE ? 12.0 : (kind == GLOW_WORMS ? 6.0 : 2.5);
      sum += tint * (strength * pattern * near);
      glow = max(glow, pattern * near);
    }
  }
  return sum;
}

// The light the haze scatters towards the eye between the camera c and the surface point p
// (both anchor-relative), linear.
vec3 lights_haze(vec3 c, vec3 p) {
  if (u_haze <= 0.0) return vec3(0.0);
  vec3 ray = p - c;
  float len = length(ray);
  vec3 v = ray / max(len, 1e-4);
  vec3 sum = vec3(0.0);
  for (int k = 0; k < u_light_count; ++k) {
    int i = u_light_index[k];
    // The part of the ray inside the light's bound.
    float t_lo = 0.0, t_hi = len;
    float bound = u_light_bound[i].w;
    if (bound > 0.0) {
      vec3 oc = c - u_light_bound[i].xyz;
      float b = dot(oc, v);
      float disc = b * b - (dot(oc, oc) - bound * bound);
      if (disc <= 0.0) continue;
      float root = sqrt(disc);
      t_lo = max(t_lo, -b - root);
      t_hi = min(t_hi, -b + root);
      if (t_hi <= t_lo) continue;
    }
    vec3 to_light = u_light_position[i].xyz - c;
    float t0 = dot(to_light, v);
    float a2 = 1.0 + max(dot(to_light, to_light) - t0 * t0, 0.0);
    float a = sqrt(a2);
    // The integral of 1 / (a^2 + u^2)^2 du: u / (2 a^2 (a^2 + u^2)) + atan(u / a) / (2 a^3).
    float u1 = t_hi - t0, u0 = t_lo - t0;
    float along = (u1 / (a2 + u1 * u1) - u0 / (a2 + u0 * u0)) / (2.0 * a2) +
                  (atan(u1 / a) - atan(u0 / a)) / (2.0 * a2 * a);
    sum += u_light_color[i].rgb * along;
  }
  return sum * u_haze;
}
