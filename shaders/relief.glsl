// The rock's relief: what the GPU adds to the streamed patch mesh.
// Written once, in the subset of GLSL 4.10 and C++/GLM that both read, and used by
//   - shaders/room.tese (spliced in by client/render/shaders.cpp): displacement and normals,
//   - shaders/room.frag: the same noise for the rock's texture,
//   - client/play (through common/relief/relief.hpp): collision with the displaced surface,
// so the player walks on what is drawn. Rules of the subset: float literals with an f, no
// swizzles, no out parameters, functions marked RELIEF_FN (inline in C++).
//
// Scales (the relief owns 5 cm to 1.5 m; the server's patch owns 1-10 m):
//   rock:        domain-warped fBm (1.4 m, 0.31 m, 0.15 m) plus one ridged octave (0.65 m),
//                amplitude from the roughness channel and a slow world-space variety field;
//   flowstone:   sheets of calcite poured over walls: smooth lobes up to 0.22 m thick that run
//                down the wall (a noise stretched 2.5x vertically), fluted by vertical curtains
//                (anisotropic ridged noise, 2.6 m tall, 0.4 m wide), the rock's relief drowned
//                beneath them (a sheet smooths what it covers);
//   formations:  stalactites, stalagmites, soda straws, columns and draperies are no relief but
//                instanced geometry (shaders/formation.glsl, common/formations/formations.hpp);
//                their candidates stay here (relief_speleothem: one per 1 m cell of a lattice
//                turned off the world axes, pulled onto the nearest crack, heavy-tailed lengths
//                from soda straws to metres in big rooms), so the relief's displacement is the
//                rock's and the flowstone's alone, under a metre along the normal.
//   occlusion:   ambient occlusion from the relief itself (Relief::occlusion, per tessellated
//                vertex: no extra pass): the rock's crevices (its finer octaves below their local
//                mean, scaled by how rough the rock is there).
//   fine detail: relief_fine, shading only (normals and albedo in room.frag, no displacement, so
//                collision is untouched): calcite and sand grain at 3.5 and 1.6 cm, solution pits
//                1-3.5 cm across, joints a few millimetres wide; every octave faded by the pixel's
//                footprint on the surface so none is ever finer than ~2 pixels (no shimmer).
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
const float kReliefCrackWidth = 0.45f;  // metres from a crack within which dripstone grows
const float kReliefSheet = 0.22f;         // metres: the thickest flowstone sheet at strength 1
const float kReliefColumnShare = 0.15f;   // of the speleothem cells: column candidates
const float kReliefColumnSpan = 2.5f;     // metres between a column cell's meeting levels

const float kReliefCrevice = 0.6f;        // occlusion at the bottom of the deepest crevice

const float kReliefOcclusionMin = 0.3f;   // the darkest ambient occlusion


// The lattice hash's per-axis multipliers: a point's hash mixes c.x * x, c.y * y and c.z * z.
const uvec3 kReliefHashAxes = uvec3(1597334673u, 3812015801u, 2798796415u);

// The hash of a lattice point from its per-axis products q = uvec3(c) * kReliefHashAxes.
RELIEF_FN float relief_hash_mixed(uint qx, uint qy, uint qz) {
  uint n = (qx ^ qy ^ qz) * 1597334673u;
  n ^= n >> 16;
  n *= 2246822519u;
  n ^= n >> 13;
  return float(n >> 8) * (1.0f / 16777216.0f);
}

// An integer lattice point to [0, 1).
RELIEF_FN float relief_hash(ivec3 c) {
  uvec3 q = uvec3(c) * kReliefHashAxes;
  return relief_hash_mixed(q.x, q.y, q.z);
}

// 3-D value noise with a quintic fade at the point f (0-1 on each axis) of lattice cell i: .x in
// [-1, 1], .yzw its analytic gradient.
RELIEF_FN vec4 relief_noise_cell(ivec3 i, vec3 f) {
  vec3 u = f * f * f * (f * (f * 6.0f - 15.0f) + 10.0f);
  vec3 du = 30.0f * f * f * (f * (f - 2.0f) + 1.0f);
  // The eight corners' hashes, sharing the per-axis products: (c + 1) * m = c * m + m, wrapping
  // alike, so these are relief_hash's bits with 3 multiplications for the corners instead of 24.
  uvec3 q0 = uvec3(i) * kReliefHashAxes;
  uvec3 q1 = q0 + kReliefHashAxes;
  float a = relief_hash_mixed(q0.x, q0.y, q0.z);
  float b = relief_hash_mixed(q1.x, q0.y, q0.z);
  float c = relief_hash_mixed(q0.x, q1.y, q0.z);
  float d = relief_hash_mixed(q1.x, q1.y, q0.z);
  float e = relief_hash_mixed(q0.x, q0.y, q1.z);
  float g = relief_hash_mixed(q1.x, q0.y, q1.z);
  float h = relief_hash_mixed(q0.x, q1.y, q1.z);
  float k = relief_hash_mixed(q1.x, q1.y, q1.z);
  float k1 = b - a, k2 = c - a, k3 = e - a, k4 = a - b - c + d, k5 = a - c - e + h,
        k6 = a - b - e + g, k7 = -a + b + c - d + e - g - h + k;
  float v = a + k1 * u.x + k2 * u.y + k3 * u.z + k4 * u.x * u.y + k5 * u.y * u.z +
            k6 * u.z * u.x + k7 * u.x * u.y * u.z;
  vec3 dv = du * vec3(k1 + k4 * u.y + k6 * u.z + k7 * u.y * u.z,
                      k2 + k5 * u.z + k4 * u.x + k7 * u.z * u.x,
                      k3 + k6 * u.x + k5 * u.y + k7 * u.x * u.y);
  return vec4(2.0f * v - 1.0f, 2.0f * dv);
}

// The same at the point x of the lattice (for points near the origin of their frame: a vein's
// source, a lattice cell's own corner).
RELIEF_FN vec4 relief_noise(vec3 x) {
  vec3 cell = floor(x);
  return relief_noise_cell(ivec3(cell), x - cell);
}

// ---- Far from the origin ----
// Sectors reach 6,291 km from the origin, where a float's step is 0.5 m: noise of world positions
// in float32 made the rock a mosaic of flat squares there. A world position is therefore a block
// of kReliefBlock metres held exactly in integers and a float offset from the block's corner that
// stays within a kilometre or two (the renderer's anchor is such a corner near the camera; C++
// callers take the block of a room's origin: relief.hpp's relief_pos_of). Every noise of the
// world runs at a whole number k of cycles per block on each axis, so the block's share of its
// lattice coordinate, block * k, is an exact integer and only the offset's is a float: the same
// precision 6,000 km out as at the origin.
const float kReliefBlock = 1024.0f;
struct ReliefPos {
  ivec3 block;  // world = block * kReliefBlock + local
  vec3 local;   // metres from the block's corner
};

RELIEF_FN ReliefPos relief_pos(ivec3 block, vec3 local) {
  ReliefPos p;
  p.block = block;
  p.local = local;
  return p;
}

// The frequency, cycles per metre, of k cycles per block.
RELIEF_FN vec3 relief_frequency(ivec3 k) {
  return vec3(k) * (1.0f / kReliefBlock);
}

// The noise at world * k / kReliefBlock + c (relief_noise's value and gradient with respect to
// that argument: times relief_frequency(k) for metres).
RELIEF_FN vec4 relief_noise_at(ReliefPos p, ivec3 k, vec3 c) {
  vec3 x = p.local * relief_frequency(k) + c;
  vec3 cell = floor(x);
  return relief_noise_cell(p.block * k + ivec3(cell), x - cell);
}

// The world's noises, cycles per block (kReliefBlock), each the nearest to the frequency it was
// designed at.
const ivec3 kReliefVarietyK = ivec3(43);                // 1 / 24 m
const ivec3 kReliefWarpK = ivec3(379);                  // 0.37
const ivec3 kReliefOctave0K = ivec3(717);               // 0.7
const ivec3 kReliefRidgeK = ivec3(1587);                // 1.55
const ivec3 kReliefOctave2K = ivec3(3277);              // 3.2
const ivec3 kReliefOctave3K = ivec3(6861);              // 6.7
const ivec3 kReliefLobeK = ivec3(563, 225, 563);        // (0.55, 0.22, 0.55)
const ivec3 kReliefScallopK = ivec3(1433, 573, 1433);   // (1.4, 0.56, 1.4): the sheet's edge
const ivec3 kReliefCurtainK = ivec3(2458, 389, 2458);   // (2.4, 0.38, 2.4)
const ivec3 kReliefGrainCoarseK = ivec3(29257);         // 1 / 3.5 cm
const ivec3 kReliefGrainFineK = ivec3(64000);           // 1 / 1.6 cm
const ivec3 kReliefPitK = ivec3(14629);                 // 1 / 7 cm
const ivec3 kReliefJointBendK = ivec3(655);             // 0.64: a joint plane's wander
const ivec3 kReliefJointRunK = ivec3(931);              // 0.91: where a joint is open
// The rock's two joint sets: planes across which each set's cycles count
// (relief_frequency: cycles per metre) goes up by one, so 1 / |k / kReliefBlock| metres apart.
// Steep (a small vertical part) and nearly square to each other, as in bedded limestone; whole
// cycles per block, so a block's corner is on a plane of each set and 6,000 km out the planes
// are as sharp as at the origin.
const ivec3 kReliefJointSetA = ivec3(1402, 90, 620);    // (1.37, 0.09, 0.61): 0.67 m apart
const ivec3 kReliefJointSetB = ivec3(-410, 60, 905);    // (-0.40, 0.06, 0.88): 1.03 m apart
const int kReliefCrackK = 164;  // 0.16: the speleothems' crack field (cracks ~6 m apart)

RELIEF_FN vec3 relief_gradient(vec4 n) {
  return vec3(n.y, n.z, n.w);
}

// The slow world-space variety field in [0, 1] (one cycle per ~24 m): bare rock against rough,
// decorated rock.
RELIEF_FN float relief_variety(ReliefPos p) {
  return 0.5f + 0.5f * relief_noise_at(p, kReliefVarietyK, vec3(17.3f, 5.1f, -9.7f)).x;
}

// The displaced surface point is p + n * height.
struct Relief {
  float height;   // metres along the normal (into the cave when positive): rock and flowstone
  vec3 gradient;  // of height with respect to world position (for the displaced normal); near
                  // rims that of the rock and flowstone before their height fades (see relief_at)
  float cavity;   // 0 in the rock's hollows, 1 on its crests (occlusion, tint)
  float spike;    // 0-1: calcite under half a flowstone sheet's thickness (room.frag's colour;
                  // formation.vert gives a formation's: 1 at its tip)
  float occlusion;  // ambient occlusion, kReliefOcclusionMin-1: 1 on open rock, less in the
                    // rock's crevices (1 without relief)
  vec3 warp;        // the rock's domain warp: its octaves are noise at p + warp
  float rock;       // metres: the rock's amplitude there (under a flowstone sheet, what shows)
};

// The rock's octaves above its broadest: their feature sizes in metres (1 / frequency).
const float kReliefRidgeSize = 0.645f;
const float kReliefOctave2Size = 0.3125f;
const float kReliefOctave3Size = 0.149f;

// The rock's octaves above its broadest at the warped point q (relief_at; relief_rock_detail).
RELIEF_FN vec4 relief_ridge_noise(ReliefPos q) {
  return relief_noise_at(q, kReliefRidgeK, vec3(31.0f, 0.0f, 0.0f));
}
RELIEF_FN vec4 relief_octave2_noise(ReliefPos q) {
  return relief_noise_at(q, kReliefOctave2K, vec3(-17.0f, 5.0f, 0.0f));
}
RELIEF_FN vec4 relief_octave3_noise(ReliefPos q) {
  return relief_noise_at(q, kReliefOctave3K, vec3(0.0f, 47.0f, 11.0f));
}

// The share of a rock octave of feature size `size` metres that a mesh sampled every `spacing`
// metres carries: all of it at four samples a feature or more, none at two or fewer, where it
// would only fold the surface into facets. What the mesh cannot carry, room.frag adds to the
// shading normal per pixel (relief_rock_detail).
RELIEF_FN float relief_octave_kept(float size, float spacing) {
  return 1.0f - smoothstep(0.25f * size, 0.5f * size, spacing);
}

// One speleothem candidate of the turned lattice: where it stands and how long it is.
struct Speleothem {
  vec2 offset;   // metres from its cell's low corner, in the turned lattice's frame (relief_turn)
  float len;     // metres: the stalactite's length (0: none); its stalagmite is 0.5-0.65 as tall
  float radius;  // metres: the stalactite's radius at its root (its stalagmite's is twice that)
  float level;   // metres in [0, kReliefColumnSpan): a column cell's meeting levels are
                 // level + k * kReliefColumnSpan; negative: not a column cell
  float form;    // 0-1: its stalagmite's form, from a bell-shaped cone (0) to a candle (1):
                 // steep-sided with a rounded top, narrower and taller (a slower drip)
};

// World x, z into the speleothem lattice's frame.
RELIEF_FN vec2 relief_turn(vec3 p) {
  return vec2(kReliefTurnCos * p.x - kReliefTurnSin * p.z,
              kReliefTurnSin * p.x + kReliefTurnCos * p.z);
}

// The crack field at `offset` metres into lattice cell c (1 m cells of the turned frame): the
// noise at (c + offset) * kReliefCrackK / kReliefBlock, its cell's whole part c * kReliefCrackK
// split in integers (exact however far out the cell is).
RELIEF_FN vec4 relief_crack_noise(ivec2 c, vec2 offset) {
  ivec2 m = c * kReliefCrackK;
  vec2 x = (vec2(m & ivec2(1023)) + offset * float(kReliefCrackK)) * (1.0f / kReliefBlock);
  vec2 cell = floor(x);
  ivec2 whole = (m >> ivec2(10)) + ivec2(cell);
  return relief_noise_cell(ivec3(whole.x, 3, whole.y), vec3(x.x - cell.x, 0.7f, x.y - cell.y));
}

// The speleothem of lattice cell c, the longest of its room being `longest` metres. Which cells
// hold one depends on the hashes and the crack field at the cell alone, so none is cut off by a
// threshold crossing it. The centre stays inside its cell, so the 3 x 3 cells around a point hold
// every speleothem that reaches it (radius at most 0.45 m, a stalagmite's 0.9 m < 1 cell).
RELIEF_FN Speleothem relief_speleothem(ivec2 c, float longest) {
  Speleothem s;
  s.offset = vec2(0.0f);
  s.len = 0.0f;
  s.radius = 0.0f;
  s.level = -1.0f;
  s.form = 0.0f;
  float jx = relief_hash(ivec3(c.x, 104729, c.y));
  float jz = relief_hash(ivec3(c.x, 1299709, c.y));
  vec2 offset = vec2(0.1f + 0.8f * jx, 0.1f + 0.8f * jz) * kReliefCell;
  // One Newton step onto the crack (the zero line of the field), then back inside the cell.
  vec4 k = relief_crack_noise(c, offset);
  vec2 g = vec2(k.y, k.w) * relief_frequency(ivec3(kReliefCrackK)).x;
  float g2 = dot(g, g) + 1e-6f;
  offset = clamp(offset - (k.x / g2) * g, vec2(0.05f * kReliefCell), vec2(0.95f * kReliefCell));
  float from_crack = abs(relief_crack_noise(c, offset).x) / sqrt(g2);
  float on_crack = 1.0f - smoothstep(0.3f * kReliefCrackWidth, kReliefCrackWidth, from_crack);
  if (relief_hash(ivec3(c.x, 7919, c.y)) >= 0.9f * on_crack) return s;
  float size = relief_hash(ivec3(c.x, 15485863, c.y));
  s.offset = offset;
  s.len = max(kReliefStraw, longest * size * size * size);
  s.radius = min(0.03f + 0.11f * s.len, 0.45f);
  s.form = relief_hash(ivec3(c.x, 2750159, c.y));
  if (relief_hash(ivec3(c.x, 611953, c.y)) < kReliefColumnShare) {
    s.level = kReliefColumnSpan * relief_hash(ivec3(c.x, 86028121, c.y));
    s.radius = 0.45f;  // columns are the thickest
  }
  return s;
}

// The longest speleothem of a room of this radius, at strength 1.
RELIEF_FN float relief_spike_length(float room_radius) {
  return clamp(kReliefSpikePerRadius * room_radius, kReliefSpikeMin, kReliefSpikeMax);
}

// How far the relief can move a point along its normal, either way: the rock's octaves sum to at
// most 0.97 in size, times its largest amplitude (variety 1.35, ceilings 1.2), plus the flowstone
// (sheet and curtains).
RELIEF_FN float relief_normal_bound(float strength) {
  return strength * (kReliefRock * 1.35f * 1.2f + kReliefFlowstone + kReliefSheet);
}

// How far the relief can move a point along its normal, either way: a bound for culling and
// collision (the formations are geometry of their own: shaders/formation.glsl).
RELIEF_FN float relief_bound(float strength) {
  return relief_normal_bound(strength);
}

// The relief at world point p on a surface with unit normal n, as drawn by a mesh sampled every
// `spacing` metres (room.tese: the tessellation's step there; 0: exactly, as relief_at below
// gives it to collision, baking and engines). roughness (0-1) is the patch's channel, rim the rim
// weight (1 on a portal rim) and strength scales everything
// (0: off). The spacing drops the rock's octaves the mesh cannot carry (relief_octave_kept).
RELIEF_FN Relief relief_at_sampled(ReliefPos p, vec3 n, float roughness, float rim, float strength,
                                   float spacing) {
  Relief r;
  r.height = 0.0f;
  r.gradient = vec3(0.0f);
  r.cavity = 0.5f;
  r.spike = 0.0f;
  r.occlusion = 1.0f;
  r.warp = vec3(0.0f);
  r.rock = 0.0f;
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
  vec3 warp = vec3(relief_noise_at(p, kReliefWarpK, vec3(3.1f, 7.7f, 1.3f)).x,
                   relief_noise_at(p, kReliefWarpK, vec3(-5.2f, 2.4f, 8.8f)).x,
                   relief_noise_at(p, kReliefWarpK, vec3(9.4f, -3.3f, 4.6f)).x);
  r.warp = 0.45f * warp;
  ReliefPos q = relief_pos(p.block, p.local + r.warp);
  // As sampled: the octaves the mesh cannot carry leave its shape (relief_octave_kept). Sampled
  // exactly (spacing 0: collision, bakes, engines), the cavity and the crevices below see the
  // whole rock; drawn, an octave the mesh cannot carry at all is not evaluated (room.frag adds it
  // to the shading: relief_rock_detail), and the cavity and crevices of a vertex that far apart
  // see the octaves it can carry.
  float kept1 = 1.0f, kept2 = 1.0f, kept3 = 1.0f;
  if (spacing > 0.0f) {
    kept1 = relief_octave_kept(kReliefRidgeSize, spacing);
    kept2 = relief_octave_kept(kReliefOctave2Size, spacing);
    kept3 = relief_octave_kept(kReliefOctave3Size, spacing);
  }
  vec4 o0 = relief_noise_at(q, kReliefOctave0K, vec3(0.0f));
  vec4 o1 = relief_ridge_noise(q);
  vec4 o2 = kept2 > 0.0f ? relief_octave2_noise(q) : vec4(0.0f);
  vec4 o3 = kept3 > 0.0f ? relief_octave3_noise(q) : vec4(0.0f);
  // A ridge softened (|x| as sqrt(x^2 + e)): crested, yet smooth enough that tessellation at
  // level 8 does not saw its crest into teeth.
  float soft = sqrt(o1.x * o1.x + 0.05f);
  float ridge = 1.0f - soft;
  float ridge_sign = o1.x / soft;
  float rock = 0.45f * o0.x + 0.28f * (2.0f * ridge * ridge - 1.0f) + 0.16f * o2.x + 0.08f * o3.x;
  float drawn = spacing > 0.0f ? 0.45f * o0.x + kept1 * 0.28f * (2.0f * ridge * ridge - 1.0f) +
                                     kept2 * 0.16f * o2.x + kept3 * 0.08f * o3.x
                               : rock;
  vec3 rock_gradient = (0.45f * 0.7f) * relief_gradient(o0) +
                       (kept1 * 0.28f * 4.0f * 1.55f) * ridge * -ridge_sign * relief_gradient(o1) +
                       (kept2 * 0.16f * 3.2f) * relief_gradient(o2) +
                       (kept3 * 0.08f * 6.7f) * relief_gradient(o3);
  // Floors are sediment (smoother), ceilings the roughest.
  float rock_amplitude = strength * kReliefRock * mix(0.35f, 1.0f, clamp(roughness, 0.0f, 1.0f)) *
                         mix(0.5f, 1.35f, variety) * mix(1.0f, 0.45f, ground) *
                         mix(1.0f, 1.2f, under);
  r.height = keep * rock_amplitude * drawn;
  r.gradient = rock_amplitude * rock_gradient;
  r.rock = rock_amplitude;
  r.cavity = clamp(0.5f + 0.6f * rock, 0.0f, 1.0f);
  // Crevices: how far the finer octaves put the point below their mean (-0.066; the 1.4 m octave
  // is the local mean they ride on), deeper where the rock is rougher (amplitude over the
  // nominal); the whole rock's height darkens the broad hollows a little. Not faded on rims, like
  // the gradient: the same in both rooms.
  float finer = 0.28f * (2.0f * ridge * ridge - 1.0f) + 0.16f * o2.x + 0.08f * o3.x;
  float below = max(-0.066f - finer, 0.0f) * rock_amplitude / (strength * kReliefRock);
  // Only the deepest hollows (below the finer octaves' 5th percentile at nominal roughness; the
  // 10th on the roughest walls): a wider band blotched whole walls like stains.
  float crevice = kReliefCrevice * smoothstep(0.12f, 0.32f, below);
  float broad = mix(0.7f, 1.0f, smoothstep(-0.45f, 0.2f, rock));

  // Flowstone: sheets poured down walls where the variety field is high, fluted by curtains.
  float flow_zone = smoothstep(0.35f, 0.65f, variety) * wall;
  if (flow_zone > 0.0f) {
    // The sheet: lobes of a noise stretched 2.5x vertically (1.8 m wide, 4.5 m tall), smooth
    // where they cover (thickness s^2 (3 - 2 s), flat on top), drowning the rock beneath. Its
    // edge is the noise's level set, which on the lattice's own axes ran straight for metres (a
    // cell of value noise thresholded: a rectangle of bare rock cut out of a sheet); the rock's
    // domain warp, doubled, bends it, and a finer octave scallops it into lobes.
    ReliefPos lobe_at = relief_pos(p.block, p.local + 2.5f * r.warp);
    vec4 lobe = relief_noise_at(lobe_at, kReliefLobeK, vec3(-41.0f, 9.0f, 23.0f));
    vec4 scallop = relief_noise_at(lobe_at, kReliefScallopK, vec3(13.0f, -29.0f, 5.0f));
    float cover = clamp((lobe.x + 0.5f * scallop.x + 0.15f) * 2.5f, 0.0f, 1.0f);
    vec3 cover_gradient =
        cover > 0.0f && cover < 1.0f
            ? 2.5f * (relief_gradient(lobe) * relief_frequency(kReliefLobeK) +
                      0.5f * relief_gradient(scallop) * relief_frequency(kReliefScallopK))
            : vec3(0.0f);
    float sheet = flow_zone * cover * cover * (3.0f - 2.0f * cover);
    vec3 sheet_gradient = flow_zone * 6.0f * cover * (1.0f - cover) * cover_gradient;
    float drown = 1.0f - 0.75f * sheet;
    float rock_height = rock_amplitude * drawn;
    float sheet_amplitude = strength * kReliefSheet;
    r.height = keep * (rock_height * drown + sheet_amplitude * sheet);
    r.gradient = r.gradient * drown - 0.75f * rock_height * sheet_gradient +
                 sheet_amplitude * sheet_gradient;
    r.cavity = mix(r.cavity, 0.85f, sheet);
    r.rock *= drown;
    crevice *= drown;  // a sheet fills the crevices it covers
    broad = mix(broad, 1.0f, sheet);
    r.spike = 0.45f * sheet;  // calcite (room.frag): tan, short of the cream of a growing tip
    vec3 scale = relief_frequency(kReliefCurtainK);
    vec4 f = relief_noise_at(p, kReliefCurtainK, vec3(0.0f, 0.0f, 73.0f));
    // A crest softened like the rock's ridge: curtains, not saw teeth.
    float f_soft = sqrt(f.x * f.x + 0.02f);
    float c = 1.0f - f_soft;
    float f_sign = f.x / f_soft;
    float amplitude = strength * kReliefFlowstone * flow_zone;
    r.height += keep * amplitude * c * c * c;
    r.gradient += amplitude * 3.0f * c * c * -f_sign * relief_gradient(f) * scale;
  }

  r.occlusion = max(broad * (1.0f - crevice), kReliefOcclusionMin);
  return r;
}

// The relief itself (relief_at_sampled, sampled exactly).
RELIEF_FN Relief relief_at(ReliefPos p, vec3 n, float roughness, float rim, float strength) {
  return relief_at_sampled(p, n, roughness, rim, strength, 0.0f);
}

// The unit normal of the surface after relief: the patch normal tilted against the height's
// tangential gradient.
RELIEF_FN vec3 relief_normal(vec3 n, vec3 gradient) {
  vec3 tangential = gradient - dot(gradient, n) * n;
  return normalize(n - tangential);
}

// Where the relief puts the surface point p (patch normal n): p + n * height.
RELIEF_FN vec3 relief_displace(vec3 p, vec3 n, Relief r) {
  return p + n * r.height;
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

// ---- Fine detail: shading below the tessellation's reach ----
// What a wall 2 m away shows at 1080p (2.6 mm pixels), which the displaced mesh cannot carry: the
// grain of calcite and sand, solution pits, hairline joints. Shading only: a tilt of the normal, a
// change of albedo and a darkening of pits and joints; relief_at's displacement (and so collision
// and the baked meshes) does not see it. Every octave fades by the pixel's footprint on the
// surface (metres a pixel covers there), to nothing before its features shrink under ~2 pixels:
// a frequency the pixel grid cannot carry is left out instead of aliasing into shimmer as the
// view moves. The joints are box-filtered over the footprint instead, so a joint thinner than
// a pixel greys the pixel by the share it covers.

const float kReliefGrainCoarse = 0.035f;  // metres: the coarser grain's lattice cell
const float kReliefGrainFine = 0.016f;    // metres: the finest grain's
const float kReliefPitCell = 0.07f;       // metres: one pit at most per cell, 1-3.5 cm across
const float kReliefPitShare = 0.35f;      // of the cells of pitted rock that hold a pit
const float kReliefPitDepth = 0.004f;     // metres
const float kReliefJointCell = 0.55f;     // metres: about the closer joint set's spacing (its
                                          // lines fade by it as they crowd on screen)
const float kReliefJointWidth = 0.0025f;  // metres: half a joint's width

struct ReliefFine {
  vec3 gradient;  // of the fine height, metres per metre (relief_normal tilts the normal by it)
  float tint;     // albedo factor round 1: the grain's light and dark crystals
  float cavity;   // 1 on open rock, less inside a pit or joint (darkens the albedo)
};

// How much of an octave whose features are `cell` metres across survives a footprint of
// `footprint` metres: all of it from 4 pixels a cell, none at 2 or fewer.
RELIEF_FN float relief_fine_fade(float cell, float footprint) {
  return smoothstep(2.0f, 4.0f, cell / max(footprint, 1e-6f));
}

// The rock's octaves that a mesh sampled every `spacing` metres could not carry
// (relief_octave_kept), as the gradient room.frag tilts the normal by: the same noises at the
// warped point p + warp (Relief::warp), times the rock's amplitude (Relief::rock), each faded
// by the pixel's footprint like the fine detail. Zero where the mesh carries them all.
RELIEF_FN vec3 relief_rock_detail(ReliefPos p, vec3 warp, float rock, float spacing,
                                  float footprint) {
  vec3 g = vec3(0.0f);
  if (!(rock > 0.0f)) return g;  // no relief (off, or the flat meshes)
  float w1 = (1.0f - relief_octave_kept(kReliefRidgeSize, spacing)) *
             relief_fine_fade(kReliefRidgeSize, footprint);
  float w2 = (1.0f - relief_octave_kept(kReliefOctave2Size, spacing)) *
             relief_fine_fade(kReliefOctave2Size, footprint);
  float w3 = (1.0f - relief_octave_kept(kReliefOctave3Size, spacing)) *
             relief_fine_fade(kReliefOctave3Size, footprint);
  ReliefPos q = relief_pos(p.block, p.local + warp);
  if (w1 > 0.0f) {
    vec4 o1 = relief_ridge_noise(q);
    float soft = sqrt(o1.x * o1.x + 0.05f);
    g += (w1 * 0.28f * 4.0f * 1.55f) * (1.0f - soft) * -(o1.x / soft) * relief_gradient(o1);
  }
  if (w2 > 0.0f) g += (w2 * 0.16f * 3.2f) * relief_gradient(relief_octave2_noise(q));
  if (w3 > 0.0f) g += (w3 * 0.08f * 6.7f) * relief_gradient(relief_octave3_noise(q));
  return rock * g;
}

// How much of a pixel a crack of joint set k covers at world point p on a surface with unit
// normal n (0-1): the set's nearest plane (each plane set off within its slab by a hash, bent by
// `bend` so it is not ruled straight; about half the planes never crack) crossed with the
// surface, `open` (0-1) as wide as it gapes there, box-filtered over the footprint measured
// across the plane. A plane that meets the surface at a glancing angle would smear its crack into
// a band: those fade out.
RELIEF_FN float relief_joint_cover(ReliefPos p, vec3 n, ivec3 k, vec4 bend, float open,
                                   float edge, float footprint) {
  vec3 f = relief_frequency(k);
  // Whole cycles per block: the block's own count is a whole number of planes, left out of t
  // but not of the planes' numbering.
  float t = dot(p.local, f) + 0.12f * bend.x;
  vec3 across = f + 0.12f * relief_gradient(bend) * relief_frequency(kReliefJointBendK);
  float rate = length(across);  // planes per metre along the plane's normal
  float slab = floor(t);
  int plane = int(slab) + p.block.x * k.x + p.block.y * k.y + p.block.z * k.z;
  if (relief_hash(ivec3(k.z, plane, k.x)) > 0.55f) return 0.0f;  // a sound plane
  float at = 0.5f + 0.6f * (relief_hash(ivec3(plane, k.x, k.z)) - 0.5f);
  float d = max(abs(t - slab - at) / rate + edge, 0.0f);  // metres from the plane
  float glancing = length(cross(n, across / rate));       // sine of the plane to the surface
  float wide = footprint * max(glancing, 0.05f);
  float w = kReliefJointWidth * (0.3f + 1.2f * open);
  float lo = max(d - 0.5f * wide, -w), hi = min(d + 0.5f * wide, w);
  return min(max(hi - lo, 0.0f) / max(wide, 1e-6f), 1.0f) * smoothstep(0.25f, 0.5f, glancing);
}

// The fine detail at world point p, unit surface normal n, for a pixel covering `footprint`
// metres of the surface. grain, pits and joints (0-1) weigh the three (room.frag: rock has all
// three, sediment grain, calcite a finer grain); a weight of 0, or a footprint too coarse for an
// octave, skips its noise.
RELIEF_FN ReliefFine relief_fine(ReliefPos p, vec3 n, float footprint, float grain, float pits,
                                 float joints) {
  ReliefFine f;
  f.gradient = vec3(0.0f);
  f.tint = 1.0f;
  f.cavity = 1.0f;
  // Grain: two octaves of value noise, 3 mm and 1 mm high, +-10 % and +-8 % of the albedo.
  float g1 = grain * relief_fine_fade(kReliefGrainCoarse, footprint);
  float jag = 0.0f;  // the coarse grain, which also roughens a joint's edges
  if (g1 > 0.0f) {
    vec4 a = relief_noise_at(p, kReliefGrainCoarseK, vec3(7.0f, 0.0f, 0.0f));
    f.gradient += (g1 * 0.003f / kReliefGrainCoarse) * relief_gradient(a);
    f.tint += g1 * 0.10f * a.x;
    jag = g1 * a.x;
    float g2 = grain * relief_fine_fade(kReliefGrainFine, footprint);
    if (g2 > 0.0f) {
      vec4 b = relief_noise_at(p, kReliefGrainFineK, vec3(0.0f, 13.0f, 0.0f));
      f.gradient += (g2 * 0.001f / kReliefGrainFine) * relief_gradient(b);
      f.tint += g2 * 0.08f * b.x;
    }
  }
  // Pits: round solution hollows, one at most per kReliefPitCell cell, centred far enough inside
  // it that the hollow never crosses the cell's faces (so no neighbour cell need be looked at):
  // a bowl of depth kReliefPitDepth, darker inside. Fades once a pit spans under ~4 pixels.
  float gp = pits * relief_fine_fade(0.5f * kReliefPitCell, footprint);
  if (gp > 0.0f) {
    vec3 x = p.local * relief_frequency(kReliefPitK);
    vec3 cell = floor(x);
    ivec3 id = p.block * kReliefPitK + ivec3(cell);
    if (relief_hash(id + ivec3(0, 0, 7001)) < kReliefPitShare) {
      vec3 centre = cell + vec3(0.3f + 0.4f * relief_hash(id + ivec3(131, 0, 0)),
                                0.3f + 0.4f * relief_hash(id + ivec3(0, 131, 0)),
                                0.3f + 0.4f * relief_hash(id + ivec3(0, 0, 131)));
      float radius = 0.12f + 0.13f * relief_hash(id + ivec3(17, 29, 31));  // cells
      vec3 r = (x - centre) * kReliefPitCell;                                  // metres
      float rm = radius * kReliefPitCell;
      float q = dot(r, r) / (rm * rm);
      if (q < 1.0f) {
        // h = -depth (1 - q)^2: a bowl; dh/dp = 4 depth (1 - q) r / rm^2.
        f.gradient += (gp * 4.0f * kReliefPitDepth * (1.0f - q) / (rm * rm)) * r;
        f.cavity *= 1.0f - 0.35f * gp * (1.0f - q);
      }
    }
  }
  // Joints: hairline cracks where the planes of the rock's two joint sets cross the surface
  // (relief_joint_cover): straight over metres, wandering a few centimetres, on any surface a
  // line, never a loop; each open in runs where a slow noise allows (one noise, the two sets at
  // its opposite signs), widest in the middle of a run and closing to a hair at its ends, their
  // edges roughened by the coarse grain where it shows. The lines fade once they crowd closer
  // than ~4 pixels.
  float gj = joints * relief_fine_fade(0.5f * kReliefJointCell, footprint);
  if (gj > 0.0f) {
    vec4 bend = relief_noise_at(p, kReliefJointBendK, vec3(19.0f, -5.0f, 37.0f));
    float run = relief_noise_at(p, kReliefJointRunK, vec3(-29.0f, 3.0f, 11.0f)).x;
    float edge = 0.0025f * jag;
    // Set A where the run noise is positive, set B where negative: one set at a point, so one
    // plane's distance to evaluate.
    bool first = run > 0.0f;
    float open = abs(run);
    float crack = smoothstep(0.0f, 0.15f, open) *
                  relief_joint_cover(p, n, first ? kReliefJointSetA : kReliefJointSetB,
                                     first ? bend : -bend, smoothstep(0.0f, 0.6f, open), edge,
                                     footprint);
    f.cavity *= 1.0f - 0.7f * gj * crack;
  }
  return f;
}
