// Light in the dark, spliced into room.frag: the world's lights (cave/lights.hpp:
// glow-worm colonies, glowing mineral seams, crystal clusters) and the player's flares as point
// lights with falloff, the glowing rock around each source, and the haze they light along the
// view ray. The renderer fills the arrays from render::frame_lights (the same list
// grotto-client --screenshot --json reports), the nearest GROTTO_MAX_LIGHTS at most.
//
// Falloff (cave/lights.hpp's convention): colour x intensity / (r^2 + d^2), windowed to zero at
// the light's range by (1 - (d / range)^4)^2 (Karis 2013, "Real Shading in Unreal Engine 4"),
// where r is the source's radius (cave::light_source_radius, passed in u_light_glow.w): 1 m for a
// flare; a glow-worm colony's patch; for a seam or crystals that light a hall, metres, so that the
// rock beside them shows its grain instead of burning white.
// Rock casts no shadows here, so a light stays in its room: it lights only what lies within its
// bound (its room's sphere, a little grown for the relief), not the next room through the rock;
// but the rooms through its room's portals get its light kLightSpill metres past the bound
// (u_light_next_door), fading into them: a passage seen from a lit hall shows its first metres
// and the dark deepening along it, not a flat black disc.
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
// Metres past its bound that a light still reaches in the rooms next to its own, fading to nothing,
// and the share of it that lights there whichever way the rock faces (bounced light).
const float kLightSpill = 7.0;
const float kLightBounce = 0.3;

uniform int u_light_count;                         // lights that can reach this room's rock
uniform int u_light_index[GROTTO_MAX_LIGHTS];      // which of the arrays' lights they are
uniform int u_haze_count;                          // lights whose haze the view rays to this
uniform int u_haze_index[GROTTO_MAX_LIGHTS];       // room's rock can cross, and which they are
uniform vec4 u_light_position[GROTTO_MAX_LIGHTS];  // xyz anchor-relative; w: range (m)
uniform vec4 u_light_color[GROTTO_MAX_LIGHTS];     // rgb: linear colour x intensity at 1 m
uniform vec4 u_light_glow[GROTTO_MAX_LIGHTS];      // x: glowing patch radius (m); y: GLOW_*;
                                                   // z: the light's own number in [0, 1);
                                                   // w: the source's radius (m)
uniform vec4 u_light_bound[GROTTO_MAX_LIGHTS];     // xyz anchor-relative centre; w: radius, 0: none
uniform float u_light_next_door[GROTTO_MAX_LIGHTS];  // by k, as u_light_index: 1 where this
                                                     // room is through a portal of the light's
                                                     // own, 0 elsewhere
uniform float u_headlamp;                          // 1: the headlamp is on; 0: off
uniform float u_haze;                              // scattering per metre of the lit haze

// soft: the source's radius (metres).
float light_falloff(float d, float range, float soft) {
  float x = d / range;
  float window = clamp(1.0 - x * x * x * x, 0.0, 1.0);
  return window * window / (soft * soft + d * d);
}

// A line `width` metres wide at signed distance d (metres) from its middle, as the share of a
// pixel covering `footprint` metres that it lights: a line thinner than the pixel fades instead of
// breaking into dashes.
float vein_line(float d, float width, float footprint) {
  float w = max(width, 1e-4);
  float cover = max(w, footprint);
  return (w / cover) * (1.0 - smoothstep(0.5 * cover, cover, abs(d)));
}

// A vein where a fracture meets the rock (limestone's calcite veins, a glowing mineral's seam):
// the plane dot(p, dir) = 0 bent by slow noise so that it wanders a few decimetres; its signed
// distance from p (metres), and its width there, `width` where widest, pinching and swelling.
float vein_plane(vec3 p, vec3 dir) {
  return dot(p, dir) + 0.6 * relief_noise(p * 0.21 + dir * 5.0).x;
}
float vein_width(vec3 p, vec3 dir, float width) {
  return width * clamp(0.55 + 0.6 * relief_noise(p * 0.9 + dir * 11.0).x, 0.1, 1.0);
}

// A vein plane through world point p (relief.glsl's ReliefPos): the plane's offset of the block's
// corner in doubles (a world coordinate 6,000 km out), the rest in floats; its noise at the
// world's own lattice (kReliefBlock's whole cycles).
float vein_plane_at(ReliefPos p, vec3 dir, float spacing) {
  double corner = dot(dvec3(p.block) * double(kReliefBlock), dvec3(dir));
  float across = float(corner - double(spacing) * floor(corner / double(spacing)));
  return across + dot(p.local, dir) +
         0.6 * relief_noise_at(p, ivec3(215), dir * 5.0).x;  // 0.21 per metre
}
float vein_width_at(ReliefPos p, vec3 dir, float width) {
  return width * clamp(0.55 + 0.6 * relief_noise_at(p, ivec3(922), dir * 11.0).x, 0.1, 1.0);
}

// The vein of one plane through p = 0 (a seam through its source).
float vein_through(vec3 p, vec3 dir, float width, float footprint) {
  return vein_line(vein_plane(p, dir), vein_width(p, dir, width), footprint);
}

// A set of such veins, planes `spacing` metres apart shifted by `phase` of it: on a wall each
// leaves a long, nearly straight trace; two sets cross, as joints do.
float vein_trace(ReliefPos p, vec3 dir, float spacing, float phase, float width, float footprint) {
  float t = vein_plane_at(p, dir, spacing) / spacing + phase;
  return vein_line((fract(t + 0.5) - 0.5) * spacing, vein_width_at(p, dir, width), footprint);
}

// A glow-worm colony's larvae (Arachnocampa): points of light a few millimetres across, one in a
// share of the cells of a `cell`-metre lattice that follows clusters (~0.5 m) and thins out
// towards the colony's ragged edge, each at its own place in its cell and of its own brightness,
// measured across the surface (normal n) so that every larva near the rock shows. A larva smaller
// than the pixel's footprint spreads over the pixel with its light kept (its peak held where it
// would wash out to white, so the colony keeps its colour); where the lattice itself is finer than
// a pixel, the colony is its mean glow, mottled by the clusters (no shimmer).
float glow_worms(ReliefPos world, vec3 n, float footprint) {
  const float cell = kReliefBlock / float(kReliefPitK.x), larva = 0.005;  // 7 cm cells
  float occupied =
      0.7 *
      (0.3 + 0.7 * smoothstep(-0.5, 0.6, relief_noise_at(world, ivec3(1946), vec3(4.0, 1.0, 0.0)).x)) *
      smoothstep(-0.6, 0.2, relief_noise_at(world, ivec3(614), vec3(0.0, 9.0, 2.0)).x);
  vec3 x = world.local / cell;
  vec3 whole = floor(x);
  ivec3 c = world.block * kReliefPitK + ivec3(whole);
  vec3 at = 0.2 + 0.6 * vec3(relief_hash(c + ivec3(11, 0, 0)), relief_hash(c + ivec3(0, 13, 0)),
                             relief_hash(c + ivec3(0, 0, 17)));
  vec3 off = (x - whole - at) * cell;
  off -= n * dot(off, n);
  // A larva's light spread over at least a pixel by a compact kernel (1 - r^2/s^2)^2, whose
  // integral, pi s^2 / 3, the 3 below undoes (a larva's light the same at every distance): it
  // reaches no further than the pixel's own footprint, so a far larva lights the one to four
  // pixels round its point, a dot, not a Gaussian's cross of five saturated pixels.
  float spread = max(larva, footprint);
  float bright = relief_hash(c) < occupied ? 0.4 + 0.6 * relief_hash(c + ivec3(5, 7, 3)) : 0.0;
  float q = max(1.0 - dot(off, off) / (spread * spread), 0.0);
  float dots = bright * 3.0 * (larva * larva) / (spread * spread) * q * q;
  // The mean over many cells: occupied x mean brightness x a larva's light over a cell's area.
  float mean = occupied * 0.7 * 3.14159 * larva * larva / (cell * cell);
  return mix(min(dots, 0.05), mean, smoothstep(0.5 * cell, cell, footprint));
}

// What the lights add to a surface point p (anchor-relative; `world` the same point in world
// space) with shading normal s, unit vector v towards the eye and albedo (occlusion applied);
// footprint: the pixel's size on the surface (metres). wrap: translucency (calcite lets light
// wrap round); through: the share of the light from behind that a thin sheet lets through, by
// colour (0: opaque). glow: the emissive mask for bloom.
vec3 lights_shade(vec3 p, ReliefPos world, vec3 s, vec3 v, vec3 albedo, float wrap, vec3 through,
                  float footprint, out float glow) {
  vec3 sum = vec3(0.0);
  glow = 0.0;
  int glow_light = -1;     // the light whose glowing patch is nearest its full strength here
  float glow_near = 0.0;
  for (int k = 0; k < u_light_count; ++k) {
    int i = u_light_index[k];
    vec3 to_light = u_light_position[i].xyz - p;
    float d = length(to_light);
    float range = u_light_position[i].w;
    if (d >= range) continue;
    float bound = u_light_bound[i].w;
    float reach = bound + kLightSpill * u_light_next_door[k];
    float from_centre = length(p - u_light_bound[i].xyz);
    float inside = bound > 0.0 ? 1.0 - smoothstep(0.9 * bound, reach, from_centre) : 1.0;
    if (inside <= 0.0) continue;
    vec3 l = to_light / max(d, 1e-4);
    int kind = int(u_light_glow[i].y + 0.5);
    float soft = u_light_glow[i].w;
    // A colony's larvae shine down and out, not along their own rock: its patch is unlit by it.
    float self_lit = kind == GLOW_WORMS ? smoothstep(0.5, 1.5, d / soft) : 1.0;
    vec3 radiance = u_light_color[i].rgb * (light_falloff(d, range, soft) * inside * self_lit);
    float facing = dot(s, l);
    float lambert = max((facing + wrap) / (1.0 + wrap), 0.0);
    // Past its room's wall, in a passage off it, the light arrives bounced off the passage's
    // walls as much as straight: a share of it lights every side (a mouth's inner walls that face
    // away from the source show, dimming inwards with the spill, instead of black).
    float bounced = bound > 0.0 ? kLightBounce * u_light_next_door[k] *
                                      smoothstep(0.85 * bound, bound, from_centre)
                                : 0.0;
    lambert = max(lambert, bounced);
    vec3 h = normalize(l + v);
    // pow(x, 24) as five multiplications (two transcendental ops a light, a pixel, saved).
    float x1 = max(dot(s, h), 0.0), x2 = x1 * x1, x4 = x2 * x2, x8 = x4 * x4;
    float sheen = x8 * x8 * x8 * 0.08;
    sum += radiance * (albedo * lambert + sheen * lambert + through * max(-facing, 0.0));

    // The source itself: its rock glows within `size` metres. Only the nearest source's patch
    // is drawn (below): patches seldom overlap, and evaluated in the loop every pattern's noise
    // ran for every light (a renderer that runs both sides of a branch, as llvmpipe does, paid it
    // for every pixel).
    float size = u_light_glow[i].x;
    if (d < size) {
      float near = 1.0 - smoothstep(0.2 * size, size, d);
      if (near > glow_near) {
        glow_near = near;
        glow_light = i;
      }
    }
  }
  if (glow_light >= 0) {
    int i = glow_light;
    int kind = int(u_light_glow[i].y + 0.5);
    float pattern;
    if (kind == GLOW_WORMS) {
      // Thousands of tiny lights: a starry patch of larvae.
      pattern = 40.0 * glow_worms(world, s, footprint);
    } else if (kind == GLOW_SEAM) {
      // The mineral's vein through the source, in a fracture's plane (its direction the light's
      // own, steep as joints are), with a thinner one crossing it.
      float a = 6.2832 * u_light_glow[i].z;
      vec3 dir = normalize(vec3(cos(a), 0.25 * sin(3.0 * a), sin(a)));
      vec3 across = normalize(cross(dir, vec3(0.3, 1.0, 0.2)));
      vec3 from_source = p - u_light_position[i].xyz;
      pattern = max(vein_through(from_source, dir, 0.09, footprint),
                    0.7 * vein_through(from_source, across, 0.035, footprint));
    } else if (kind == GLOW_CRYSTALS) {
      // Facets: cells of noise that catch and hold the light.
      pattern = smoothstep(0.25, 0.6, relief_noise_at(world, ivec3(4096), vec3(0.0, 0.0, 11.0)).x);
    } else {
      pattern = 1.0;  // a flare: its own spot of rock is white hot
    }
    vec3 tint = u_light_color[i].rgb / max(max(u_light_color[i].r, u_light_color[i].g),
                                           max(u_light_color[i].b, 1e-4));
    float strength = kind == GLOW_FLARE ? 12.0 : 2.5;
    sum += tint * (strength * pattern * glow_near);
    glow = pattern * glow_near;
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
  for (int k = 0; k < u_haze_count; ++k) {
    int i = u_haze_index[k];
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
    // A colony lights the haze from its whole patch: a wide, faint glow, no hot centre. A seam's
    // or crystals' halo stays a point's, a few metres round the source.
    float soft = int(u_light_glow[i].y + 0.5) == GLOW_WORMS ? u_light_glow[i].w : 1.0;
    float a2 = soft * soft + max(dot(to_light, to_light) - t0 * t0, 0.0);
    float a = sqrt(a2);
    // The integral of 1 / (a^2 + u^2)^2 du: u / (2 a^2 (a^2 + u^2)) + atan(u / a) / (2 a^3).
    float u1 = t_hi - t0, u0 = t_lo - t0;
    float along = (u1 / (a2 + u1 * u1) - u0 / (a2 + u0 * u0)) / (2.0 * a2) +
                  (atan(u1 / a) - atan(u0 / a)) / (2.0 * a2 * a);
    sum += u_light_color[i].rgb * along;
  }
  return sum * u_haze;
}
