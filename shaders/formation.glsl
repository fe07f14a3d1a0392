// Speleothems as geometry (issue 43; DESIGN "Formations, 1 cm-4 m"): the shape of one formation
// instance, written once in the subset of GLSL 4.10 and C++/GLM that relief.glsl uses, and read by
//   - shaders/formation.vert: each instance's smooth mesh (a surface of revolution bent by the
//     instance's own profile, rings, bulbs and irregularity),
//   - shaders/formations.{hpp,cpp}: placement (the root's flare reaches into the rock) and the
//     simple shapes walkers and flares collide with,
// so what is drawn, what collides and what the tests measure is one function.
//
// An instance is a vertical axis through its root (where it leaves the rock): a stalactite hangs
// down from a ceiling, a stalagmite and a column stand up from a floor (a column's far end is in
// the ceiling). s is metres along the axis from the root (negative: inside the rock, where the
// root keeps flaring so that no gap opens whatever the rock's relief does round it), theta the
// angle round it.
#ifndef RELIEF_FN
#define RELIEF_FN
#endif

const int kFormationStalactite = 0;
const int kFormationStalagmite = 1;
const int kFormationColumn = 2;

struct FormationShape {
  vec3 root;         // metres: where the axis leaves the rock (room frame, or anchor-relative)
  float length;      // metres from the root to the tip (a column: to the ceiling's root)
  float radius;      // metres: the radius at the root, above its flare
  float tip;         // metres: the radius at the tip (a soda straw keeps its radius)
  float embed;       // metres the mesh reaches past the root into the rock (both ends of a column)
  int kind;          // kFormationStalactite, kFormationStalagmite or kFormationColumn
  float taper;       // stalactites: the profile's exponent (1 a cone, 2-3 concave); stalagmites:
                     // e of (1 - sqrt(u))^(1/e), 2 a bell-shaped cone to 6 a candle; columns: the
                     // waist, 0-1
  float flare;       // how much wider than `radius` the root is where it meets the rock
  float rings;       // relative depth of the growth rings
  float bulbs;       // relative size of the bulbs (water that ran down and left a swelling)
  float seed;        // 0-1: the phase of its rings, bulbs and irregularity
  float yaw;         // radians: its turn about the axis
};

// The axis's direction: down for stalactites, up for the rest.
RELIEF_FN float formation_direction(FormationShape f) {
  return f.kind == kFormationStalactite ? -1.0f : 1.0f;
}

// The span of the mesh along the axis: from -embed to length (+ embed for a column).
RELIEF_FN float formation_start(FormationShape f) {
  return -f.embed;
}
RELIEF_FN float formation_end(FormationShape f) {
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

// The radius at s metres along the axis and angle theta (radians) round it. Zero at a tip.
RELIEF_FN float formation_radius(FormationShape f, float s, float theta) {
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

// The point of the surface at s metres along the axis and angle theta (radians).
RELIEF_FN vec3 formation_point(FormationShape f, float s, float theta) {
  float r = formation_radius(f, s, theta);
  float a = theta + f.yaw;
  return f.root + vec3(r * cos(a), formation_direction(f) * s, r * sin(a));
}

// The largest radius anywhere along the visible part: culling and collision bounds.
RELIEF_FN float formation_bound_radius(FormationShape f) {
  return f.radius * (1.0f + f.flare) * (1.0f + f.rings) * (1.0f + f.bulbs) * 1.12f;
}
