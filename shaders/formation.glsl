// Speleothems as geometry (formations from 1 cm to 4 m long): the shape of one formation
// instance, written once in the subset of GLSL 4.10 and C++/GLM that relief.glsl uses, and read by
//   - shaders/formation.vert: each instance's smooth mesh (a surface of revolution bent by the
//     instance's own profile, rings, bulbs and irregularity),
//   - common/formations/formations.{hpp,cpp}: placement (the root's flare reaches into the rock) and the
//     simple shapes walkers and flares collide with,
// so what is drawn, what collides and what the tests measure is one function.
//
// An instance is a vertical axis through its root (where it leaves the rock): a stalactite hangs
// down from a ceiling, a stalagmite and a column stand up from a floor (a column's far end is in
// the ceiling). s is metres along the axis from the root (negative: inside the rock, where the
// root keeps flaring so that no gap opens whatever the rock's relief does round it), theta the
// angle round it.
//
// A drapery (a curtain: calcite deposited by water trickling down an inclined ceiling along a
// line) is a thin sheet hanging from that line, longest in its middle, its lower edge in tongues
// and beaded, folded more towards the bottom, banded. It uses the same mesh the other way round:
// s runs across it, from -radius to radius along its line, and theta round the loop of its
// cross-section, from its top edge inside the rock (theta 0) down its front face to its lower
// edge (pi) and up its back.
//
// A boulder (a block fallen from the ceiling of a breakdown chamber, 0.3-4 m) lies on the floor:
// a convex slab, angular. Its plan is a polygon of 5-7 faces (corners from its seed, stretched
// across by `tip`), each face a plane leaning in or out on its own; its top a plane that may
// tilt, with a corner broken off by a steeper one on most blocks; its top edge chamfered. Its s
// runs over its profile rather than up an axis: from its bottom (embed below the root, in the
// floor) up its side, over the chamfer and across its top to the middle, each part a fixed share
// of the span so every level of detail keeps a ring on the top edge; its theta runs round its
// faces, one face a sector of the mesh, the points crowded towards the corners so that the
// edges stay sharp (boulder_point).
#ifndef RELIEF_FN
#define RELIEF_FN
#endif

const int kFormationStalactite = 0;
const int kFormationStalagmite = 1;
const int kFormationColumn = 2;
const int kFormationDrapery = 3;
const int kFormationBoulder = 4;

struct FormationShape {
  vec3 root;         // metres: where the axis leaves the rock (room frame, or anchor-relative);
                     // a drapery's: the middle of its top edge
  float length;      // metres from the root to the tip (a column: to the ceiling's root); a
                     // drapery's longest drop
  float radius;      // metres: the radius at the root, above its flare; a drapery's half width
  float tip;         // metres: the radius at the tip (a soda straw keeps its radius); a
                     // drapery's half thickness
  float embed;       // metres the mesh reaches past the root into the rock (both ends of a
                     // column; a drapery's whole top edge; a boulder's bottom, in the floor)
  int kind;          // kFormationStalactite, kFormationStalagmite, kFormationColumn,
                     // kFormationDrapery or kFormationBoulder
  float taper;       // stalactites: the profile's exponent (1 a cone, 2-3 concave); stalagmites:
                     // e of (1 - sqrt(u))^(1/e), 2 a bell-shaped cone to 6 a candle; columns: the
                     // waist, 0-1; draperies: metres of fold at the lower edge; boulders: the
                     // top's slope (metres per metre)
  float flare;       // how much wider than `radius` the root is where it meets the rock;
                     // draperies: folds across the width; boulders: the top's slope's direction
                     // (radians from the block's own x axis)
  float rings;       // relative depth of the growth rings; a drapery's slope: metres its line
                     // rises per metre along (it follows its ceiling); a boulder's chamfer (share
                     // of its radius)
  float bulbs;       // relative size of the bulbs (water that ran down and left a swelling); a
                     // drapery's bead along its lower edge; how much a boulder's faces lean in
                     // on average (share of the plan lost from the floor to its top's height)
  float seed;        // 0-1: the phase of its rings, bulbs and irregularity (a boulder's faces)
  float yaw;         // radians: its turn about the axis (a drapery's line: (cos, 0, sin))
  float tint;        // 0-1: its calcite's colour along formation_colour's palette (white, cream,
                     // orange and brown with iron, grey with manganese); boulders: 0
  float wet;         // 0-1: how wet it is (active: a water film, a sharp highlight; dry: matte)
};
// A boulder reads `root` as the middle of its base on the floor, `length` as its top's height
// there, `radius` as its plan's largest radius and `tip` as its plan's width across over its
// length (0.5-1).

// A speleothem's calcite colour (linear albedo) at palette position `tint`: pure calcite white,
// cream, then orange and brown where iron stained it, and grey where manganese did.
RELIEF_FN vec3 formation_colour(float tint) {
  vec3 white = vec3(0.80f, 0.79f, 0.75f), cream = vec3(0.74f, 0.66f, 0.52f);
  vec3 orange = vec3(0.66f, 0.42f, 0.22f), brown = vec3(0.40f, 0.26f, 0.15f);
  vec3 grey = vec3(0.33f, 0.32f, 0.31f);
  float t = clamp(tint, 0.0f, 1.0f);
  if (t < 0.3f) return mix(white, cream, t / 0.3f);
  if (t < 0.55f) return mix(cream, orange, (t - 0.3f) / 0.25f);
  if (t < 0.8f) return mix(orange, brown, (t - 0.55f) / 0.25f);
  return mix(brown, grey, (t - 0.8f) / 0.2f);
}

// The axis's direction: down for stalactites and draperies, up for the rest.
RELIEF_FN float formation_direction(FormationShape f) {
  return f.kind == kFormationStalactite || f.kind == kFormationDrapery ? -1.0f : 1.0f;
}

// The span of the mesh's s: from -embed to length (+ embed for a column); across a drapery, from
// one end of its line to the other.
RELIEF_FN float formation_start(FormationShape f) {
  return f.kind == kFormationDrapery ? -f.radius : -f.embed;
}
RELIEF_FN float formation_end(FormationShape f) {
  if (f.kind == kFormationDrapery) return f.radius;
  return f.kind == kFormationColumn ? f.length + f.embed : f.length;
}

// The root's flare: 1 + flare at the rock, back to 1 over a few radii; past the root (inside the
// rock) it keeps widening, so the rock always cuts the formation where it is wide.
RELIEF_FN float formation_flare(float from_root, float radius, float flare, float embed) {
  float reach = 0.03f + 1.5f * radius;
  if (from_root < 0.0f) return (1.0f + flare) * (1.0f + 0.6f * (-from_root) / max(embed, 1e-3f));
  float x = from_root / reach;
  return 1.0f + flare / (1.0f + 3.0f * x * x * x);
}

// A boulder's own hash of (its seed, n), 0-1: integers, so C++ and every GPU agree.
RELIEF_FN float boulder_hash(FormationShape f, int n) {
  uint x = uint(f.seed * 65536.0f) * 747796405u + uint(n) * 2891336453u;
  x ^= x >> 16;
  x *= 2246822519u;
  x ^= x >> 13;
  x *= 3266489917u;
  x ^= x >> 16;
  return float(x >> 8) * (1.0f / 16777216.0f);
}

// A boulder's faces, in its own frame (before `yaw`): at height y over the root its plan is the
// polygon where dot(n[k], x) <= h[k] * (1 - lean[k] * y / length) for every face k < count, a
// convex polygon whatever its corners; its top the lower of two planes, the first through
// (0, length) rising `taper` per metre towards `flare`, the second (a broken corner: cut_slope 0
// where there is none) falling cut_slope per metre past cut_at metres along cut_dir. The whole
// block then leans `tilt` radians towards tilt_dir about its root.
struct BoulderFaces {
  vec2 n[7];
  float h[7];
  float lean[7];
  float corner[8];  // the corners' directions, rising: corner[count] = corner[0] + 2 pi
  int count;
  vec2 cut_dir;
  float cut_at;
  float cut_slope;
  vec2 tilt_dir;  // the block leans this way (it lies on the floor's rubble, not level)
  float tilt;     // radians
};

RELIEF_FN BoulderFaces boulder_faces(FormationShape f) {
  BoulderFaces b;
  b.count = 5 + min(int(3.0f * f.seed), 2);
  vec2 p[7];
  for (int k = 0; k < 7; ++k) {
    float a = 6.2831853f * (float(k) + 0.36f * (boulder_hash(f, k) - 0.5f)) / float(b.count);
    float r = f.radius * (0.8f + 0.2f * boulder_hash(f, 8 + k));
    p[k] = vec2(r * cos(a), f.tip * r * sin(a));
    // Its direction, unwrapped to a's turn (stretching across keeps it in a's quadrant).
    float seen = atan(p[k].y, p[k].x);
    b.corner[k] = seen + 6.2831853f * floor((a - seen) / 6.2831853f + 0.5f);
  }
  b.corner[7] = 0.0f;
  b.corner[b.count] = b.corner[0] + 6.2831853f;
  for (int k = 0; k < 7; ++k) {
    vec2 q = p[k + 1 < b.count ? k + 1 : 0];
    vec2 n = normalize(vec2(q.y - p[k].y, p[k].x - q.x));  // outward: the corners run anticlockwise
    b.n[k] = k < b.count ? n : vec2(1.0f, 0.0f);
    b.h[k] = k < b.count ? dot(n, p[k]) : 1e9f;
    b.lean[k] = f.bulbs * mix(-0.6f, 1.6f, boulder_hash(f, 16 + k));
  }
  float turn = 6.2831853f * boulder_hash(f, 30);
  b.cut_dir = vec2(cos(turn), sin(turn));
  b.cut_at = mix(0.3f, 0.75f, boulder_hash(f, 31)) * f.radius;
  // At most 0.45 x length lower at the plan's edge.
  b.cut_slope = boulder_hash(f, 32) < 0.6f
                    ? min(mix(0.4f, 1.0f, boulder_hash(f, 33)),
                          0.45f * f.length / max(f.radius - b.cut_at, 1e-3f))
                    : 0.0f;
  float lean_to = 6.2831853f * boulder_hash(f, 34);
  b.tilt_dir = vec2(cos(lean_to), sin(lean_to));
  b.tilt = 0.15f * boulder_hash(f, 35);
  return b;
}

// The metres from a boulder's axis to its side at height y, in direction theta of its frame.
RELIEF_FN float boulder_side(FormationShape f, BoulderFaces b, float theta, float y) {
  vec2 d = vec2(cos(theta), sin(theta));
  float rise = max(y, -f.length) / max(f.length, 1e-3f);
  float r = 1e9f;
  for (int k = 0; k < 7; ++k) {
    float toward = dot(b.n[k], d);
    if (k < b.count && toward > 1e-4f) r = min(r, b.h[k] * (1.0f - b.lean[k] * rise) / toward);
  }
  return r;
}

// A boulder's plan: the metres from its axis to its side at the root's height, in direction theta
// of its own frame (before `yaw`, and before it leans: the leaning moves it by centimetres).
RELIEF_FN float boulder_plan(FormationShape f, float theta) {
  return boulder_side(f, boulder_faces(f), theta, 0.0f);
}

// The height of a boulder's top over its root at x (metres, its own frame).
RELIEF_FN float boulder_top(FormationShape f, BoulderFaces b, vec2 x) {
  float plane = f.length + f.taper * dot(x, vec2(cos(f.flare), sin(f.flare)));
  return min(plane, f.length + b.cut_slope * (b.cut_at - dot(x, b.cut_dir)));
}

// The point of a boulder at s (formation_start to formation_end) and theta (the mesh's angle).
// By share u of the span: its side from the bottom up to the chamfer (u to 0.3075: formation.vert's
// ring at 3/8 of the grid), the chamfer (to 0.5: its ring at 1/2, in every level of detail but the
// coarsest), the top to the middle; within each part the rings crowd towards the edges, so the
// normals the mesh interpolates between its rings turn over a thin band at each edge, not across
// a face. Round it, each of count sectors of the mesh spans one face, its points crowded towards
// the corners.
RELIEF_FN vec3 boulder_point(FormationShape f, float s, float theta) {
  BoulderFaces b = boulder_faces(f);
  float turns = theta / 6.2831853f;
  float m = (turns - floor(turns)) * float(b.count);
  int j = min(int(m), b.count - 1);
  float t = m - float(j);
  t -= 0.85f * sin(6.2831853f * t) / 6.2831853f;
  float angle = mix(b.corner[j], b.corner[j + 1], t);
  vec2 d = vec2(cos(angle), sin(angle));
  // Where the side meets the top: y = top(side(y) d), a few steps from the top's middle.
  float edge = f.length;
  for (int i = 0; i < 3; ++i) edge = boulder_top(f, b, boulder_side(f, b, angle, edge) * d);
  float chamfer = min(f.rings * f.radius, 0.3f * max(edge, 0.0f));
  float low = edge - chamfer;
  float inner = max(boulder_side(f, b, angle, edge) - chamfer, 0.0f);
  float u = clamp((s + f.embed) / max(f.length + f.embed, 1e-3f), 0.0f, 1.0f);
  const float b1 = 0.3074806f, b2 = 0.5f;
  float r, y;
  if (u < b1) {
    // The bottom reaches further down by what the lean lifts it on its high side (the plan
    // reaches 1.35 radii at most), so it stays embed x cos(tilt) or more under the root all round.
    float v = 1.0f - u / b1;
    y = mix(low, -f.embed - 1.35f * f.radius * tan(b.tilt), v * v * v);
    r = boulder_side(f, b, angle, y);
  } else if (u < b2) {
    float v = (u - b1) / (b2 - b1);
    v -= 0.85f * sin(6.2831853f * v) / 6.2831853f;
    r = mix(boulder_side(f, b, angle, low), inner, v);
    y = mix(low, boulder_top(f, b, inner * d), v);
  } else {
    float v = (u - b2) / (1.0f - b2);
    r = inner * (1.0f - v * v);
    y = boulder_top(f, b, r * d);
  }
  // Lean about the root, then turn by yaw.
  vec2 x = r * d;
  float along = dot(x, b.tilt_dir);
  float c = cos(b.tilt), sn = sin(b.tilt);
  x += b.tilt_dir * (along * c + y * sn - along);
  y = y * c - along * sn;
  float cy = cos(f.yaw), sy = sin(f.yaw);
  return vec3(x.x * cy - x.y * sy, y, x.x * sy + x.y * cy);
}

// The radius at s metres along the axis and angle theta (radians) round it. Zero at a tip. A
// boulder's: how far from its axis its profile is at s.
RELIEF_FN float formation_radius(FormationShape f, float s, float theta) {
  if (f.kind == kFormationBoulder) {
    vec3 at = boulder_point(f, s, theta);
    return length(vec2(at.x, at.z));
  }
  float len = max(f.length, 1e-3f);
  float u = clamp(s / len, 0.0f, 1.0f);
  float body = f.radius;
  float flare = formation_flare(s, f.radius, f.flare, f.embed);
  if (f.kind == kFormationStalactite) {
    // Concave from the root to a narrow tip, which closes in a round end of the tip's radius.
    body = mix(f.tip, f.radius, pow(1.0f - u, f.taper));
    float end = max(len - s, 0.0f) / max(f.tip, 1e-3f);
    body *= sqrt(clamp(end * (2.0f - min(end, 1.0f)), 0.0f, 1.0f));
  } else if (f.kind == kFormationStalagmite) {
    // The relief's old stalagmite across, as a radius up the height: (1 - sqrt(u))^(1/e).
    body = f.radius * pow(max(1.0f - sqrt(u), 0.0f), 1.0f / f.taper);
  } else {
    // A column: flared at both ends, narrower in its waist.
    float far_flare = formation_flare(formation_end(f) - f.embed - s, f.radius, f.flare, f.embed);
    flare = max(flare, far_flare);
    float w = 4.0f * u * (1.0f - u);
    body = f.radius * (1.0f - f.taper * 0.45f * w * w);
  }
  float phase = 6.2831853f * f.seed;
  // Growth rings a few centimetres apart, shallow; bulbs where water ran and left calcite.
  float rings = 1.0f + f.rings * sin(s * 52.0f + 40.0f * phase) * (0.6f + 0.4f * sin(s * 7.0f));
  float b = sin(s * (2.1f + 1.3f * f.seed) + phase);
  float bulbs = 1.0f + f.bulbs * b * b * b * b;
  // Not a lathe's work: two slow lobes round the axis that turn as it grows.
  float irregular = 1.0f + 0.07f * sin(2.0f * theta + phase + 2.3f * s) +
                    0.04f * sin(3.0f * theta - 2.0f * phase - 4.1f * s);
  return body * flare * rings * bulbs * irregular;
}

// A drapery's line (along) and the horizontal across it.
RELIEF_FN vec3 drapery_along(FormationShape f) {
  return vec3(cos(f.yaw), 0.0f, sin(f.yaw));
}
RELIEF_FN vec3 drapery_across(FormationShape f) {
  return vec3(-sin(f.yaw), 0.0f, cos(f.yaw));
}

// The point of a drapery's line (along its ceiling, at the root's level) x metres from the root.
RELIEF_FN vec3 drapery_line(FormationShape f, float x) {
  return f.root + drapery_along(f) * x + vec3(0.0f, f.rings * x, 0.0f);
}

// A drapery's drop at x metres along its line: longest in the middle, nothing at its ends, the
// lower edge hanging in rounded tongues, one every other fold.
RELIEF_FN float drapery_drop(FormationShape f, float x) {
  float e = clamp(x / max(f.radius, 1e-3f), -1.0f, 1.0f);
  float phase = 6.2831853f * f.seed;
  float outline = sqrt(max(1.0f - e * e, 0.0f));
  float tongues = 1.0f + 0.14f * sin(1.5707963f * f.flare * (e + 1.0f) + phase) +
                  0.06f * sin(4.0f * e - 2.0f * phase);
  return f.length * outline * tongues;
}

// How far below its line the loop of a drapery's cross-section at theta lies where its drop is
// `drop` (negative: above, in the rock). The loop's first step from the top (theta 0, embed
// above the line) reaches the line: the rest of the loop's points lie along the drop, closer
// together towards the lower edge.
RELIEF_FN float drapery_depth(FormationShape f, float drop, float theta) {
  float q = 0.5f - 0.5f * cos(theta);
  return q * drop - f.embed * max(1.0f - q / 0.035f, 0.0f);
}

// The point of a drapery at x metres along its line and theta round its cross-section.
RELIEF_FN vec3 drapery_point(FormationShape f, float x, float theta) {
  float drop = drapery_drop(f, x);
  float h = drapery_depth(f, drop, theta);
  float u = clamp(h / max(drop, 1e-3f), 0.0f, 1.0f);
  float e = clamp(x / max(f.radius, 1e-3f), -1.0f, 1.0f);
  float phase = 6.2831853f * f.seed;
  // Thicker where it leaves the rock, a bead along the lower edge, a knife's edge at its ends.
  float thick = f.tip * (1.0f + 2.0f * (1.0f - smoothstep(0.0f, 0.15f, h))) *
                (1.0f + f.bulbs * smoothstep(0.75f, 0.95f, u)) *
                sqrt(sqrt(max(1.0f - e * e, 0.0f)));
  // Folds: the sheet waves across its width, more towards its lower edge, the waves turning a
  // little as it grows.
  float fold = f.taper * (0.45f + 0.55f * u) *
               sin(3.14159265f * f.flare * (e + 1.0f) + phase + 1.2f * u);
  return drapery_line(f, x) + drapery_across(f) * (fold + thick * sin(theta)) +
         vec3(0.0f, -h, 0.0f);
}

// The point of the surface at s metres along the axis and angle theta (radians); a drapery's at
// s across it (drapery_point).
RELIEF_FN vec3 formation_point(FormationShape f, float s, float theta) {
  if (f.kind == kFormationDrapery) return drapery_point(f, s, theta);
  if (f.kind == kFormationBoulder) return f.root + boulder_point(f, s, theta);
  float r = formation_radius(f, s, theta);
  float a = theta + f.yaw;
  return f.root + vec3(r * cos(a), formation_direction(f) * s, r * sin(a));
}

// A direction out of the surface at (s, theta), point p: the normal is turned to agree with it.
RELIEF_FN vec3 formation_outward(FormationShape f, float s, float theta, vec3 p) {
  if (f.kind == kFormationDrapery)
    return drapery_across(f) * sin(theta) + vec3(0.0f, 0.5f * cos(theta), 0.0f);
  // A boulder is convex: away from a point inside it (its top is at least a quarter of its
  // length high).
  if (f.kind == kFormationBoulder) return p - (f.root + vec3(0.0f, 0.12f * f.length, 0.0f));
  vec3 out_dir = p - (f.root + vec3(0.0f, formation_direction(f) * s, 0.0f));
  return dot(out_dir, out_dir) < 1e-12f ? vec3(0.0f, formation_direction(f), 0.0f) : out_dir;
}

// How old the calcite is at (s, theta), 0-1 (t_spike: ochre at 0, cream towards 1): youngest at
// a stalactite's or stalagmite's tip, old at both ends of a column. A drapery's is 1 + u, u the
// share of its drop (0 at its top, 1 at its lower edge): linear between the mesh's points, so
// room.frag draws its bands parallel to the lower edge per pixel (the "bacon" of iron-stained and
// clean calcite), finer than the mesh's 8 points down a face could carry. A boulder is no
// calcite: -1, which room.frag shades as the walls' limestone.
RELIEF_FN float formation_age(FormationShape f, float s, float theta) {
  if (f.kind == kFormationBoulder) return -1.0f;
  if (f.kind == kFormationDrapery) {
    float drop = drapery_drop(f, s);
    return 1.0f + clamp(drapery_depth(f, drop, theta) / max(drop, 1e-3f), 0.0f, 1.0f);
  }
  float u = clamp(s / max(f.length, 1e-3f), 0.0f, 1.0f);
  if (f.kind == kFormationColumn) return 0.35f + 0.15f * sin(3.14159f * u);
  if (f.kind == kFormationStalagmite) return 0.2f + 0.45f * u * u;
  return 0.3f + 0.7f * u;
}

// A sphere holding the visible instance (its centre, in the instance's frame, and radius):
// culling.
RELIEF_FN vec3 formation_centre(FormationShape f) {
  // A drapery's: below its root (formation_reach covers its line's slope).
  if (f.kind == kFormationDrapery) return f.root + vec3(0.0f, -0.5f * f.length, 0.0f);
  return f.root + vec3(0.0f, formation_direction(f) * 0.5f * formation_end(f), 0.0f);
}

// The largest radius anywhere along the visible part: culling and collision bounds (a
// drapery's: how far it reaches from its root horizontally).
RELIEF_FN float formation_bound_radius(FormationShape f) {
  // A boulder's corners are within its radius at the floor; faces leaning out and its tilt reach
  // further.
  if (f.kind == kFormationBoulder) return f.radius * (1.0f + 0.6f * f.bulbs) + 0.15f * f.length;
  if (f.kind == kFormationDrapery) return f.radius + f.taper + 3.0f * f.tip * (1.0f + f.bulbs);
  return f.radius * (1.0f + f.flare) * (1.0f + f.rings) * (1.0f + f.bulbs) * 1.12f;
}
RELIEF_FN float formation_reach(FormationShape f) {
  if (f.kind == kFormationDrapery)
    return sqrt(0.5625f * f.length * f.length +  // the drop reaches 1.2 x length
                formation_bound_radius(f) * formation_bound_radius(f)) +
           abs(f.rings) * f.radius;
  if (f.kind == kFormationBoulder)  // its top tilts up to taper x radius above its middle
    return 0.5f * f.length + f.taper * f.radius + formation_bound_radius(f);
  return 0.5f * formation_end(f) + formation_bound_radius(f);
}
