// The rock's relief: what the GPU adds to the streamed patch mesh (DESIGN "the detail stage").
// Written once, in the subset of GLSL 4.10 and C++/GLM that both read, and used by
//   - shaders/room.tese (spliced in by client/render/shaders.cpp): displacement and normals,
//   - shaders/room.frag: the same noise for the rock's texture,
//   - client/play (through shaders/relief.hpp): collision with the displaced surface,
// so the player walks on what is drawn. Rules of the subset: float literals with an f, no
// swizzles, no out parameters, functions marked RELIEF_FN (inline in C++).
//
// Scales (the relief owns 5 cm to 1.5 m; the server's patch owns 1-10 m):
//   rock:        domain-warped fBm (1.4 m, 0.31 m, 0.15 m) plus one ridged octave (0.65 m),
//                amplitude from the roughness channel and a slow world-space variety field;
//   flowstone:   vertical curtains on walls (anisotropic ridged noise, 2.6 m tall, 0.4 m wide);
//   speleothems: stalactites on undersides and stalagmites on the floors beneath them, hanging
//                plumb: a vertical displacement (Relief::hang, -y under a stalactite, +y on a
//                stalagmite) apart from the rock's height along the normal, so dripstone on a
//                sloping ceiling hangs straight down, not out along the slope like a fang. One
//                candidate per 1 m cell of the horizontal plane (a lattice turned off the world
//                axes), pulled onto the nearest crack (the zero line of a slow 2-D noise: water
//                seeps along joints, so dripstone grows in rows with bare rock between) and kept
//                only near one. Lengths are heavy-tailed, from 5 cm soda straws to several metres
//                in big rooms (the cube of a uniform hash: most are short, a few long); a
//                stalagmite stands under each, half as tall, twice as wide and rounded on top
//                (thesis §5.5: underside bias from the world-space normal).
// The displacement is zero on portal rims (rim weight 1), so the seams between rooms stay where
// the server put them; the shading (gradient, cavity) is not faded there, so the rim is no smooth
// pale strip (docs/GALLERY.md, "The rim strip").
#ifndef RELIEF_FN
#define RELIEF_FN
#endif

const float kReliefRock = 0.30f;        // metres of rock relief at roughness 1, strength 1
const float kReliefFlowstone = 0.14f;   // metres of flowstone curtain at strength 1
const float kReliefCell = 1.0f;         // metres: speleothem cell in the horizontal plane
// The speleothem lattice is turned 29 degrees off the world axes: passages often run along x or
// z, and a lattice aligned with them lines its spikes up along the passage.
const float kReliefTurnCos = 0.8746197f;
const float kReliefTurnSin = 0.4848096f;
const float kReliefSpikeMax = 3.5f;     // metres: the longest stalactite at strength 1
const float kReliefSpikeMin = 0.35f;    // metres: the longest stalactite of the smallest rooms
const float kReliefSpikePerRadius = 0.2f;  // spike length per metre of room radius
const float kReliefStraw = 0.05f;       // metres: the shortest speleothem (a soda straw)
const float kReliefCrackScale = 0.16f;  // cycles per metre of the crack field (~6 m apart)
const float kReliefCrackWidth = 0.45f;  // metres from a crack within which dripstone grows

// An integer lattice point to [0, 1).
RELIEF_FN float relief_hash(ivec3 c) {
  uvec3 q = uvec3(c) * uvec3(1597334673u, 3812015801u, 2798796415u);
  uint n = (q.x ^ q.y ^ q.z) * 1597334673u;
  n ^= n >> 16;
  n *= 2246822519u;
  n ^= n >> 13;
  return float(n >> 8) * (1.0f / 16777216.0f);
}

// 3-D value noise with a quintic fade: .x in [-1, 1], .yzw its analytic gradient.
RELIEF_FN vec4 relief_noise(vec3 x) {
  vec3 cell = floor(x);
  ivec3 i = ivec3(cell);
  vec3 f = x - cell;
  vec3 u = f * f * f * (f * (f * 6.0f - 15.0f) + 10.0f);
  vec3 du = 30.0f * f * f * (f * (f - 2.0f) + 1.0f);
  float a = relief_hash(i + ivec3(0, 0, 0));
  float b = relief_hash(i + ivec3(1, 0, 0));
  float c = relief_hash(i + ivec3(0, 1, 0));
  float d = relief_hash(i + ivec3(1, 1, 0));
  float e = relief_hash(i + ivec3(0, 0, 1));
  float g = relief_hash(i + ivec3(1, 0, 1));
  float h = relief_hash(i + ivec3(0, 1, 1));
  float k = relief_hash(i + ivec3(1, 1, 1));
  float k1 = b - a, k2 = c - a, k3 = e - a, k4 = a - b - c + d, k5 = a - c - e + h,
        k6 = a - b - e + g, k7 = -a + b + c - d + e - g - h + k;
  float v = a + k1 * u.x + k2 * u.y + k3 * u.z + k4 * u.x * u.y + k5 * u.y * u.z +
            k6 * u.z * u.x + k7 * u.x * u.y * u.z;
  vec3 dv = du * vec3(k1 + k4 * u.y + k6 * u.z + k7 * u.y * u.z,
                      k2 + k5 * u.z + k4 * u.x + k7 * u.z * u.x,
                      k3 + k6 * u.x + k5 * u.y + k7 * u.x * u.y);
  return vec4(2.0f * v - 1.0f, 2.0f * dv);
}

RELIEF_FN vec3 relief_gradient(vec4 n) {
  return vec3(n.y, n.z, n.w);
}

// The slow world-space variety field in [0, 1] (one cycle per ~24 m): bare rock against rough,
// decorated rock.
RELIEF_FN float relief_variety(vec3 p) {
  return 0.5f + 0.5f * relief_noise(p * (1.0f / 24.0f) + vec3(17.3f, 5.1f, -9.7f)).x;
}

// The displaced surface point is p + n * height + (0, hang, 0).
struct Relief {
  float height;   // metres along the normal (into the cave when positive): rock and flowstone
  vec3 gradient;  // of height with respect to world position (for the displaced normal); near
                  // rims that of the rock and flowstone before their height fades (see relief_at)
  float hang;     // metres along world +y: speleothems (negative under a stalactite)
  vec3 hang_gradient;  // of hang with respect to world position (its y is 0)
  float cavity;   // 0 in the rock's hollows, 1 on its crests (occlusion, tint)
  float spike;    // 0-1: how far up a speleothem the point is (1 at its tip; calcite)
};

// One speleothem candidate of the turned lattice: where it stands and how long it is.
struct Speleothem {
  vec2 centre;   // metres, in the turned lattice's frame (relief_turn)
  float len;     // metres: the stalactite's length (0: none); its stalagmite is half as tall
  float radius;  // metres: the stalactite's radius at its root (its stalagmite's is twice that)
};

// World x, z into the speleothem lattice's frame.
RELIEF_FN vec2 relief_turn(vec3 p) {
  return vec2(kReliefTurnCos * p.x - kReliefTurnSin * p.z,
              kReliefTurnSin * p.x + kReliefTurnCos * p.z);
}

// The speleothem of lattice cell c, the longest of its room being `longest` metres. Which cells
// hold one depends on the hashes and the crack field at the cell alone, so none is cut off by a
// threshold crossing it. The centre stays inside its cell, so the 3 x 3 cells around a point hold
// every speleothem that reaches it (radius at most 0.45 m, a stalagmite's 0.9 m < 1 cell).
RELIEF_FN Speleothem relief_speleothem(ivec2 c, float longest) {
  Speleothem s;
  s.centre = vec2(0.0f);
  s.len = 0.0f;
  s.radius = 0.0f;
  float jx = relief_hash(ivec3(c.x, 104729, c.y));
  float jz = relief_hash(ivec3(c.x, 1299709, c.y));
  vec2 lo = vec2(c) * kReliefCell;
  vec2 centre = lo + vec2(0.1f + 0.8f * jx, 0.1f + 0.8f * jz) * kReliefCell;
  // One Newton step onto the crack (the zero line of the field), then back inside the cell.
  vec4 k = relief_noise(vec3(centre.x * kReliefCrackScale, 3.7f, centre.y * kReliefCrackScale));
  vec2 g = vec2(k.y, k.w) * kReliefCrackScale;
  float g2 = dot(g, g) + 1e-6f;
  centre = clamp(centre - (k.x / g2) * g, lo + vec2(0.05f * kReliefCell),
                 lo + vec2(0.95f * kReliefCell));
  float from_crack = abs(relief_noise(vec3(centre.x * kReliefCrackScale, 3.7f,
                                           centre.y * kReliefCrackScale)).x) / sqrt(g2);
  float on_crack = 1.0f - smoothstep(0.3f * kReliefCrackWidth, kReliefCrackWidth, from_crack);
  if (relief_hash(ivec3(c.x, 7919, c.y)) >= 0.9f * on_crack) return s;
  float size = relief_hash(ivec3(c.x, 15485863, c.y));
  s.centre = centre;
  s.len = max(kReliefStraw, longest * size * size * size);
  s.radius = min(0.03f + 0.11f * s.len, 0.45f);
  return s;
}

// The longest speleothem of a room of this radius, at strength 1.
RELIEF_FN float relief_spike_length(float room_radius) {
  return clamp(kReliefSpikePerRadius * room_radius, kReliefSpikeMin, kReliefSpikeMax);
}

// How far the relief can move a point, either way: a bound for culling. The rock's octaves sum
// to at most 0.97 in size, times its largest amplitude (variety 1.35, ceilings 1.2); flowstone
// and speleothems add their full heights.
RELIEF_FN float relief_bound(float strength, float room_radius) {
  return strength *
         (kReliefRock * 1.35f * 1.2f + kReliefFlowstone + relief_spike_length(room_radius));
}

// The relief at world point p on a surface with unit normal n. roughness (0-1) is the patch's
// channel, rim the rim weight (1 on a portal rim), room_radius the room's sphere radius and
// strength scales everything (0: off).
RELIEF_FN Relief relief_at(vec3 p, vec3 n, float roughness, float rim, float room_radius,
                           float strength) {
  Relief r;
  r.height = 0.0f;
  r.gradient = vec3(0.0f);
  r.hang = 0.0f;
  r.hang_gradient = vec3(0.0f);
  r.cavity = 0.5f;
  r.spike = 0.0f;
  if (!(strength > 0.0f)) return r;
  // Near a rim the rock's and the flowstone's heights fade (exactly zero on the rim, whatever
  // rounding did to the rim weight: the neighbouring room puts the same vertex there), but not
  // their gradient and cavity: faded with the height they left a smooth, evenly lit strip along
  // every rim that showed as a pale line. The lighting bends over rock that is flatter than it
  // looks there; the rock's gradient and cavity depend on p, n and roughness alone, the same in
  // both rooms, so the shading stays continuous across the seam. Speleothems fade whole: their
  // length depends on the room's radius, which the two rooms do not share.
  float keep = 1.0f - clamp(rim, 0.0f, 1.0f);
  keep = keep < 1e-4f ? 0.0f : keep * keep * (3.0f - 2.0f * keep);
  float variety = relief_variety(p);
  float up = n.y;
  float under = smoothstep(0.3f, 0.8f, -up);
  float ground = smoothstep(0.55f, 0.9f, up);
  float wall = 1.0f - smoothstep(0.45f, 0.85f, abs(up));

  // Rock: fBm and one ridged octave over a domain-warped position. The warp's own Jacobian is
  // left out of the gradient (it bends the lighting of the rock slightly, not its shape).
  vec3 w = p * 0.37f;
  vec3 warp = vec3(relief_noise(w + vec3(3.1f, 7.7f, 1.3f)).x,
                   relief_noise(w + vec3(-5.2f, 2.4f, 8.8f)).x,
                   relief_noise(w + vec3(9.4f, -3.3f, 4.6f)).x);
  vec3 q = p + 0.45f * warp;
  vec4 o0 = relief_noise(q * 0.7f);
  vec4 o1 = relief_noise(q * 1.55f + vec3(31.0f, 0.0f, 0.0f));
  vec4 o2 = relief_noise(q * 3.2f + vec3(-17.0f, 5.0f, 0.0f));
  vec4 o3 = relief_noise(q * 6.7f + vec3(0.0f, 47.0f, 11.0f));
  // A ridge softened (|x| as sqrt(x^2 + e)): crested, yet smooth enough that tessellation at
  // level 8 does not saw its crest into teeth.
  float soft = sqrt(o1.x * o1.x + 0.05f);
  float ridge = 1.0f - soft;
  float ridge_sign = o1.x / soft;
  float rock = 0.45f * o0.x + 0.28f * (2.0f * ridge * ridge - 1.0f) + 0.16f * o2.x + 0.08f * o3.x;
  vec3 rock_gradient = (0.45f * 0.7f) * relief_gradient(o0) +
                       (0.28f * 4.0f * 1.55f) * ridge * -ridge_sign * relief_gradient(o1) +
                       (0.16f * 3.2f) * relief_gradient(o2) + (0.08f * 6.7f) * relief_gradient(o3);
  // Floors are sediment (smoother), ceilings the roughest.
  float rock_amplitude = strength * kReliefRock * mix(0.35f, 1.0f, clamp(roughness, 0.0f, 1.0f)) *
                         mix(0.5f, 1.35f, variety) * mix(1.0f, 0.45f, ground) *
                         mix(1.0f, 1.2f, under);
  r.height = keep * rock_amplitude * rock;
  r.gradient = rock_amplitude * rock_gradient;
  r.cavity = clamp(0.5f + 0.6f * rock, 0.0f, 1.0f);

  // Flowstone: curtains hanging down walls where the variety field is high.
  float flow_zone = smoothstep(0.35f, 0.65f, variety) * wall;
  if (flow_zone > 0.0f) {
    vec3 scale = vec3(2.4f, 0.38f, 2.4f);
    vec4 f = relief_noise(p * scale + vec3(0.0f, 0.0f, 73.0f));
    // A crest softened like the rock's ridge: curtains, not saw teeth.
    float f_soft = sqrt(f.x * f.x + 0.02f);
    float c = 1.0f - f_soft;
    float f_sign = f.x / f_soft;
    float amplitude = strength * kReliefFlowstone * flow_zone;
    r.height += keep * amplitude * c * c * c;
    r.gradient += amplitude * 3.0f * c * c * -f_sign * relief_gradient(f) * scale;
  }

  // Speleothems: the tallest of the 3 x 3 cells around p wins, displacing p vertically.
  if (under > 0.0f || ground > 0.0f) {
    // Bare zones have shorter ones.
    float longest = strength * relief_spike_length(room_radius) * keep *
                    mix(0.45f, 1.0f, smoothstep(0.3f, 0.75f, variety));
    vec2 here = relief_turn(p);
    ivec2 base = ivec2(floor(here / kReliefCell));
    float best = 0.0f;
    float best_length = 1.0f;
    vec2 best_gradient = vec2(0.0f);
    for (int dz = -1; dz <= 1; ++dz) {
      for (int dx = -1; dx <= 1; ++dx) {
        Speleothem sp = relief_speleothem(base + ivec2(dx, dz), longest);
        if (!(sp.len > 0.0f) || !(longest > 0.0f)) continue;
        vec2 d = here - sp.centre;
        float dist = length(d);
        // Stalactite: a concave cone, sharp at its tip; hangs down (negative hang).
        float t = 1.0f - dist / sp.radius;
        if (under > 0.0f && t > 0.0f) {
          float h = under * sp.len * t * t;
          if (h > best) {
            best = h;
            best_length = under * sp.len;
            // d/dp of -h: +2 under len t / (r dist) d.
            best_gradient = dist > 1e-5f ? (2.0f * under * sp.len * t / (sp.radius * dist)) * d
                                         : vec2(0.0f);
          }
        }
        // Stalagmite beneath it: half as tall, twice as wide, rounded on top; stands up.
        float rf = 2.0f * sp.radius;
        float s = dist / rf;
        if (ground > 0.0f && s < 1.0f) {
          float lf = 0.5f * sp.len * ground;
          float h = lf * (1.0f - s * s) * (1.0f - s * s);
          if (h > best) {
            best = h;
            best_length = lf;
            best_gradient = (-4.0f * lf * (1.0f - s * s) / (rf * rf)) * d;
          }
        }
      }
    }
    // Under a ceiling the winner hangs (down), on a floor it stands (up).
    r.hang = under > 0.0f ? -best : best;
    r.hang_gradient =
        vec3(kReliefTurnCos * best_gradient.x + kReliefTurnSin * best_gradient.y, 0.0f,
             kReliefTurnCos * best_gradient.y - kReliefTurnSin * best_gradient.x);
    r.spike = best > 0.0f ? clamp(best / best_length, 0.0f, 1.0f) : 0.0f;
  }
  return r;
}

// The unit normal of the surface after relief: the patch normal tilted against the height's
// tangential gradient.
RELIEF_FN vec3 relief_normal(vec3 n, vec3 gradient) {
  vec3 tangential = gradient - dot(gradient, n) * n;
  return normalize(n - tangential);
}

// The unit normal of the surface p + n * height(p) + (0, hang(p), 0) over a locally flat patch
// with unit normal n: the cross product of the displaced surface's derivatives along a tangent
// frame of n (any right-handed frame gives the same normal). Without hang it is relief_normal.
RELIEF_FN vec3 relief_displaced_normal(vec3 n, vec3 gradient, vec3 hang_gradient) {
  vec3 axis = abs(n.y) < 0.9f ? vec3(0.0f, 1.0f, 0.0f) : vec3(1.0f, 0.0f, 0.0f);
  vec3 t1 = normalize(cross(axis, n));
  vec3 t2 = cross(n, t1);
  vec3 up = vec3(0.0f, 1.0f, 0.0f);
  vec3 d1 = t1 + n * dot(gradient, t1) + up * dot(hang_gradient, t1);
  vec3 d2 = t2 + n * dot(gradient, t2) + up * dot(hang_gradient, t2);
  return normalize(cross(d1, d2));
}

// Where the relief puts the surface point p (patch normal n): p + n * height + (0, hang, 0).
RELIEF_FN vec3 relief_displace(vec3 p, vec3 n, Relief r) {
  return p + n * r.height + vec3(0.0f, r.hang, 0.0f);
}

// A PN triangle (Vlachos et al. 2001) at barycentric w over corners p and normals n: the curved
// surface the relief sits on.
RELIEF_FN vec3 relief_pn_control(vec3 a, vec3 na, vec3 b) {
  return (2.0f * a + b - dot(b - a, na) * na) * (1.0f / 3.0f);
}

RELIEF_FN vec3 relief_pn_point(vec3 p0, vec3 p1, vec3 p2, vec3 n0, vec3 n1, vec3 n2, vec3 w) {
  vec3 b210 = relief_pn_control(p0, n0, p1), b120 = relief_pn_control(p1, n1, p0);
  vec3 b021 = relief_pn_control(p1, n1, p2), b012 = relief_pn_control(p2, n2, p1);
  vec3 b102 = relief_pn_control(p2, n2, p0), b201 = relief_pn_control(p0, n0, p2);
  vec3 e = (b210 + b120 + b021 + b012 + b102 + b201) * (1.0f / 6.0f);
  vec3 v = (p0 + p1 + p2) * (1.0f / 3.0f);
  vec3 b111 = e + (e - v) * 0.5f;
  float u = w.x, vv = w.y, t = w.z;
  return p0 * (u * u * u) + p1 * (vv * vv * vv) + p2 * (t * t * t) + b210 * (3.0f * u * u * vv) +
         b120 * (3.0f * u * vv * vv) + b201 * (3.0f * u * u * t) + b021 * (3.0f * vv * vv * t) +
         b102 * (3.0f * u * t * t) + b012 * (3.0f * vv * t * t) + b111 * (6.0f * u * vv * t);
}
