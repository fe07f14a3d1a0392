/* The per-vertex room deformation (thesis §3.1.4-3.1.6), written once in the common subset of
 * C++ and OpenCL C. common/mesh/deform.hpp includes it as the CPU reference; kernels/deform.cl
 * is compiled with it prepended. One text, two compilers, FP contraction off in both and
 * correctly rounded division and sqrt in OpenCL: the results are bit-identical.
 *
 * The including side defines, before including:
 *   GROTTO_FN         function qualifier             (C++: inline)
 *   GROTTO_CONSTANT   address space of shared tables (C++: nothing, OpenCL: __constant)
 *   GROTTO_F3(x,y,z)  a float3 value                 (C++: float3{x,y,z}, OpenCL: (float3)(x,y,z))
 *   grotto_sqrt, grotto_floor                        (C++: std::sqrt, std::floor on float)
 * and the types float3 (with + - * / by scalar, unary -) and uint.
 *
 * Only + - * / sqrt floor are used: no builtin dot/normalize/mix (they may fuse or use rsqrt). */

#define GROTTO_MAX_PORTALS 16
#define GROTTO_MAX_OCTAVES 6

/* A portal of the room being deformed, in the room's frame (metres from the room origin).
 * 16 floats, no float3 members, so the layout is the same on host and device. */
typedef struct {
  float cx, cy, cz;    /* disc centre */
  float nx, ny, nz;    /* unit normal, out of the room */
  float e1x, e1y, e1z; /* canonical in-plane basis (shared by both rooms of the portal) */
  float e2x, e2y, e2z;
  float radius; /* disc radius */
  float pad0, pad1, pad2;
} GrottoPortal;

/* One room of a batch. 16 floats/uints. */
typedef struct {
  float ox, oy, oz;    /* sphere centre in the room frame (|o| < one grid step) */
  float radius;        /* sphere radius */
  float wx, wy, wz;    /* room origin in noise space: world origin modulo the noise period */
  float big_amplitude; /* amplitude of the large-room octave (0 for small rooms) */
  uint first_portal;   /* index into the batch's portal table */
  uint portal_count;
  uint first_vertex; /* index of the room's first vertex in the batch */
  uint vertex_count;
  uint lod; /* which GrottoShape of the batch's table (0 detail, 1 patch) */
  float pad1, pad2, pad3;
} GrottoRoom;

/* Noise and shape parameters of one level of detail. 32 floats/uints. */
typedef struct {
  uint octaves;                        /* surface octaves (thesis §3.1.6) */
  float frequency[GROTTO_MAX_OCTAVES]; /* cycles per metre */
  float amplitude[GROTTO_MAX_OCTAVES]; /* metres */
  float rim_frequency, rim_amplitude;  /* irregular portal rims, as a fraction of the radius */
  float fade_distance;                 /* surface noise fades in over this distance from portals */
  float big_frequency, big_fade_distance; /* the large-room octave, faded out near portals */
  float roundness;                        /* 0: thesis tubes; 1: keep the sphere far from portals */
  float tension;                          /* Hermite tangent length as a fraction of the span */
  float remove_band;                      /* vertices closer than this to a portal plane go */
  float pad[11];
} GrottoShape;

GROTTO_FN float grotto_dot(float3 a, float3 b) {
  return a.x * b.x + a.y * b.y + a.z * b.z;
}
GROTTO_FN float grotto_length(float3 a) {
  return grotto_sqrt(grotto_dot(a, a));
}
GROTTO_FN float grotto_clamp01(float x) {
  return x < 0.0f ? 0.0f : (x > 1.0f ? 1.0f : x);
}
GROTTO_FN float grotto_smooth(float x) {
  x = grotto_clamp01(x);
  return x * x * (3.0f - 2.0f * x);
}

/* Improved Perlin noise (Perlin 2002), in [-1, 1] roughly; perm has 512 entries (256 twice). */
GROTTO_FN float grotto_grad(uint h, float x, float y, float z) {
  uint k = h & 15u;
  float u = k < 8u ? x : y;
  float v = k < 4u ? y : (k == 12u || k == 14u ? x : z);
  return ((k & 1u) ? -u : u) + ((k & 2u) ? -v : v);
}
GROTTO_FN float grotto_fade(float t) {
  return t * t * t * (t * (t * 6.0f - 15.0f) + 10.0f);
}
GROTTO_FN float grotto_lerp(float t, float a, float b) {
  return a + t * (b - a);
}

GROTTO_FN float grotto_noise(GROTTO_CONSTANT const unsigned char* perm, float x, float y, float z) {
  float fx = grotto_floor(x), fy = grotto_floor(y), fz = grotto_floor(z);
  /* Wrap to the 256-cell period; floats keep integers exact well beyond that. */
  uint X = (uint)((int)fx & 255), Y = (uint)((int)fy & 255), Z = (uint)((int)fz & 255);
  x -= fx;
  y -= fy;
  z -= fz;
  float u = grotto_fade(x), v = grotto_fade(y), w = grotto_fade(z);
  uint A = perm[X] + Y, AA = perm[A] + Z, AB = perm[A + 1u] + Z;
  uint B = perm[X + 1u] + Y, BA = perm[B] + Z, BB = perm[B + 1u] + Z;
  return grotto_lerp(
      w,
      grotto_lerp(
          v, grotto_lerp(u, grotto_grad(perm[AA], x, y, z), grotto_grad(perm[BA], x - 1.0f, y, z)),
          grotto_lerp(u, grotto_grad(perm[AB], x, y - 1.0f, z),
                      grotto_grad(perm[BB], x - 1.0f, y - 1.0f, z))),
      grotto_lerp(v,
                  grotto_lerp(u, grotto_grad(perm[AA + 1u], x, y, z - 1.0f),
                              grotto_grad(perm[BA + 1u], x - 1.0f, y, z - 1.0f)),
                  grotto_lerp(u, grotto_grad(perm[AB + 1u], x, y - 1.0f, z - 1.0f),
                              grotto_grad(perm[BB + 1u], x - 1.0f, y - 1.0f, z - 1.0f))));
}

GROTTO_FN float grotto_noise3(GROTTO_CONSTANT const unsigned char* perm, float3 p, float f) {
  return grotto_noise(perm, p.x * f, p.y * f, p.z * f);
}

/* Thesis §3.1.6: the portal's radius varies with noise sampled on the rim, so rims are irregular.
 * u is the unit in-plane direction from the disc centre; w0 the room origin in noise space. */
GROTTO_FN float grotto_rim_radius(GROTTO_CONSTANT const unsigned char* perm,
                                  GROTTO_CONSTANT const GrottoPortal* p,
                                  GROTTO_CONSTANT const GrottoShape* s, float3 w0, float3 u) {
  float3 c = GROTTO_F3(p->cx, p->cy, p->cz);
  float3 on_rim = w0 + c + u * p->radius;
  return p->radius * (1.0f + s->rim_amplitude * grotto_noise3(perm, on_rim, s->rim_frequency));
}

/* The unit in-plane direction from a portal's centre towards the point nearest to v. */
GROTTO_FN float3 grotto_rim_direction(GROTTO_CONSTANT const GrottoPortal* p, float3 v) {
  float3 c = GROTTO_F3(p->cx, p->cy, p->cz);
  float3 n = GROTTO_F3(p->nx, p->ny, p->nz);
  float3 rel = v - c;
  float3 in_plane = rel - n * grotto_dot(rel, n);
  float len = grotto_length(in_plane);
  if (len < 1e-6f) return GROTTO_F3(p->e1x, p->e1y, p->e1z);
  return in_plane / len;
}

/* The smallest height of p above the room's portal planes (negative: beyond a portal). */
GROTTO_FN float grotto_least_height(GROTTO_CONSTANT const GrottoPortal* portals, uint n, float3 p) {
  float least = 3.4e38f;
  for (uint i = 0; i < n; ++i) {
    GROTTO_CONSTANT const GrottoPortal* q = portals + i;
    float h = -grotto_dot(p - GROTTO_F3(q->cx, q->cy, q->cz), GROTTO_F3(q->nx, q->ny, q->nz));
    least = h < least ? h : least;
  }
  return least;
}

/* Cubic Hermite basis (thesis §3.1.4: the spline between two portal rims). */
GROTTO_FN float3 grotto_hermite(float3 p0, float3 t0, float3 p1, float3 t1, float t) {
  float t2 = t * t, t3 = t2 * t;
  float h00 = 2.0f * t3 - 3.0f * t2 + 1.0f;
  float h10 = t3 - 2.0f * t2 + t;
  float h01 = -2.0f * t3 + 3.0f * t2;
  float h11 = t3 - t2;
  return p0 * h00 + t0 * h10 + p1 * h01 + t1 * h11;
}

/* Deforms one donor-sphere vertex (unit direction dir) of a room. Returns the position in the room
 * frame; *clearance receives the smallest distance to a portal plane on the room's side
 * (negative when the vertex ended beyond a portal: it will be removed). */
GROTTO_FN float3 grotto_deform_vertex(GROTTO_CONSTANT const unsigned char* perm,
                                      GROTTO_CONSTANT const GrottoShape* s,
                                      GROTTO_CONSTANT const GrottoRoom* room,
                                      GROTTO_CONSTANT const GrottoPortal* portals, float3 dir,
                                      float* clearance) {
  float3 o = GROTTO_F3(room->ox, room->oy, room->oz);
  float3 w0 = GROTTO_F3(room->wx, room->wy, room->wz);
  float3 v = o + dir * room->radius;
  uint n = room->portal_count;

  /* Per portal: the vertex's height above the plane (room side positive), its rim point with
   * irregular radius, and the plain rim point on the smooth disc. */
  float height[GROTTO_MAX_PORTALS];
  float3 rim[GROTTO_MAX_PORTALS];
  float3 rim_dir[GROTTO_MAX_PORTALS];
  for (uint i = 0; i < n; ++i) {
    GROTTO_CONSTANT const GrottoPortal* p = portals + i;
    float3 c = GROTTO_F3(p->cx, p->cy, p->cz);
    float3 nn = GROTTO_F3(p->nx, p->ny, p->nz);
    height[i] = -grotto_dot(v - c, nn);
    rim_dir[i] = grotto_rim_direction(p, v);
    rim[i] = c + rim_dir[i] * grotto_rim_radius(perm, p, s, w0, rim_dir[i]);
  }

  /* Thesis §3.1.4-3.1.5: project onto the Hermite spline between every pair of portal rims, the
   * parameter from the heights above the two planes, and blend the pairs weighted by how close
   * each projection is to the vertex. The axis (the same spline through the disc centres) gives
   * the outward direction for noise. */
  float3 sum = GROTTO_F3(0.0f, 0.0f, 0.0f), axis_sum = GROTTO_F3(0.0f, 0.0f, 0.0f);
  float weight_sum = 0.0f;
  for (uint i = 0; i < n; ++i) {
    for (uint j = i + 1u; j < n; ++j) {
      GROTTO_CONSTANT const GrottoPortal* pi = portals + i;
      GROTTO_CONSTANT const GrottoPortal* pj = portals + j;
      float hi = height[i] > 0.0f ? height[i] : 0.0f;
      float hj = height[j] > 0.0f ? height[j] : 0.0f;
      float t = hi + hj > 0.0f ? hi / (hi + hj) : 0.5f;
      float3 ni = GROTTO_F3(pi->nx, pi->ny, pi->nz), nj = GROTTO_F3(pj->nx, pj->ny, pj->nz);
      float span = grotto_length(rim[j] - rim[i]) * s->tension;
      float3 h = grotto_hermite(rim[i], -ni * span, rim[j], nj * span, t);
      float3 ci = GROTTO_F3(pi->cx, pi->cy, pi->cz), cj = GROTTO_F3(pj->cx, pj->cy, pj->cz);
      float axis_span = grotto_length(cj - ci) * s->tension;
      float3 a = grotto_hermite(ci, -ni * axis_span, cj, nj * axis_span, t);
      float3 d = h - v;
      float wgt = 1.0f / (grotto_dot(d, d) + 1e-4f);
      sum = sum + h * wgt;
      axis_sum = axis_sum + a * wgt;
      weight_sum = weight_sum + wgt;
    }
  }
  float3 smooth_pos, axis;
  if (weight_sum > 0.0f) {
    smooth_pos = sum / weight_sum;
    axis = axis_sum / weight_sum;
  } else {
    /* A dead end (one portal): the sphere itself, bent onto the irregular rim near the portal. */
    smooth_pos = v;
    axis = o;
    if (n == 1u) {
      GROTTO_CONSTANT const GrottoPortal* p = portals;
      float3 c = GROTTO_F3(p->cx, p->cy, p->cz);
      float3 plain = c + rim_dir[0] * p->radius;
      float pull = 1.0f - grotto_smooth(height[0] / (0.5f * room->radius));
      smooth_pos = v + (rim[0] - plain) * pull;
    }
  }

  /* Far from portals a room may keep some of its sphere (caverns stay round). */
  float nearest = grotto_least_height(portals, n, smooth_pos);
  float keep = s->roundness * grotto_smooth(nearest / room->radius);
  smooth_pos = smooth_pos + (v - smooth_pos) * keep;
  axis = axis + (o - axis) * keep;

  /* Thesis §3.1.6: world-space noise along the outward direction, faded to nothing at portal
   * planes so rims stay where the neighbour expects them; big rooms get a low octave too. */
  float3 out = smooth_pos - axis;
  float out_len = grotto_length(out);
  out = out_len > 1e-6f ? out / out_len : dir;
  float3 wp = w0 + smooth_pos;
  float displacement = 0.0f;
  for (uint k = 0; k < s->octaves; ++k) {
    displacement = displacement + s->amplitude[k] * grotto_noise3(perm, wp, s->frequency[k]);
  }
  displacement = displacement * grotto_smooth(nearest / s->fade_distance);
  displacement = displacement + room->big_amplitude * grotto_noise3(perm, wp, s->big_frequency) *
                                    grotto_smooth(nearest / s->big_fade_distance);
  float3 pos = smooth_pos + out * displacement;

  *clearance = grotto_least_height(portals, n, pos);
  return pos;
}
