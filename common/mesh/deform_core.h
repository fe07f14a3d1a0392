/* The per-vertex room deformation (thesis §3.1.4-3.1.6), written once in the common subset of
 * C++ and OpenCL C. common/mesh/deform.hpp includes it as the CPU reference;
 * common/kernels/deform.cl is compiled with it prepended. One text, two compilers, FP contraction
 * off in both and correctly rounded division and sqrt in OpenCL: the results are bit-identical.
 *
 * Lanes. Per-vertex values have the type gfloat (and guint, and gmask for comparisons), which
 * is float on the CPU and on GPUs and float8 on CPU OpenCL devices: there one work item deforms
 * eight vertices of one room at once in SIMD registers, because PoCL does not vectorize this
 * kernel across work items. Every lane performs exactly the scalar operations, so lanes stay
 * bit-identical to the C++ reference. Room, portal and shape data are the same for all lanes
 * (plain float); the portal loops therefore run the same number of times in every lane. The rules
 * that make one text serve both: per-lane choices are written as `c ? a : b` with c a comparison
 * (OpenCL selects per lane by the comparison's sign bit), never `if`; a branch may only depend on
 * room data.
 *
 * The including side defines, before including:
 *   GROTTO_FN            function qualifier              (C++: inline)
 *   GROTTO_CONSTANT      address space of shared tables  (C++: nothing, OpenCL: __constant)
 *   gfloat, guint        per-lane float and uint; gmask the type of a per-lane comparison
 *   gfloat3              a struct of three gfloat named x, y, z
 *   GROTTO_WRAP256(f)    (uint)((int)f & 255) in every lane, f already floored
 *   GROTTO_SPLAT(x)      the float x in every lane of a gfloat (C++'s vector lanes, unlike
 *                        OpenCL's, do not convert a scalar on initialization)
 *   grotto_sqrt, grotto_floor, and the type uint.
 * The C++ lanes (common/mesh/deform_lanes.hpp) include this text a second time, in another
 * namespace with vector types.
 *
 * Only + - * / sqrt floor are used: no builtin dot/normalize/mix (they may fuse or use rsqrt). */

#define GROTTO_MAX_PORTALS 16
#define GROTTO_MAX_OCTAVES 6
#define GROTTO_MAX_BEDS 16

/* A portal of the room being deformed, in the room's frame (metres from the room origin).
 * 24 floats, no float3 members, so the layout is the same on host and device. */
typedef struct {
  float cx, cy, cz;    /* disc centre */
  float nx, ny, nz;    /* unit normal, out of the room */
  float e1x, e1y, e1z; /* canonical in-plane basis (shared by both rooms of the portal) */
  float e2x, e2y, e2z;
  float radius; /* disc radius */
  /* The passage's section (cave::PassageSection, from the geology), in radii: an ellipse of
   * half-width half_w and half-height half_h, its height along up_c * e1 + up_s * e2, and below
   * the centre a slot slot_width wide each side with a flat floor slot_depth down (0: none).
   * reach and narrow: its farthest and nearest extent. */
  float up_c, up_s, half_w, half_h, slot_depth, slot_width, reach, narrow;
  float pad[3];
} GrottoPortal;

/* One room of a batch. 27 + 2 x GROTTO_MAX_BEDS floats/uints. */
typedef struct {
  float ox, oy, oz;    /* sphere centre in the room frame (|o| < one grid step) */
  float radius;        /* sphere radius */
  float wx, wy, wz;    /* room origin in noise space: world origin modulo the noise period */
  float big_amplitude; /* amplitude of the large-room octave (0 for small rooms) */
  uint first_portal;   /* index into the batch's portal table */
  uint portal_count;
  uint first_vertex; /* index of the room's first vertex in the batch */
  uint vertex_count;
  uint lod;        /* which GrottoShape of the batch's table (0 detail, 1 patch) */
  uint noise_seed; /* the room's world's noise seed: a batch may mix worlds */
  uint has_floor;  /* 1: the wall rests on a floor at floor_y (the layout's cave::floor_height) */
  float floor_y;   /* in the room frame */
  /* A room's ceiling (cave::room_ceiling; ceiling_squash 0: none): above ceiling_y (room frame)
   * the wall is lowered by ceiling_squash x a ramp that eases in over ceiling_bend metres. */
  float ceiling_y, ceiling_bend, ceiling_squash;
  /* OpenCL only: the room's donor's first group of directions in the device's resident copy
   * (common/kernels/deform.cl); the CPU paths read their donor directly. */
  uint first_direction;
  /* A hall's beds (cave::bed_breaks; bed_count 0: none): the pole (unit), and bed_count breaks
   * between packages of beds, bed_at metres along it from the sphere's centre (ascending), each
   * package's wall set back bed_notch metres (soft packages weather back into notches, hard ones
   * stand as ledges). The ceiling steps along them (bed_step 0-1). */
  float bed_nx, bed_ny, bed_nz;
  uint bed_count;
  float bed_step;
  float bed_at[GROTTO_MAX_BEDS];
  float bed_notch[GROTTO_MAX_BEDS];
  /* A passage's growth (two portals; 0 otherwise): how much it widens across and grows along its
   * height halfway between its ends (fractions; room_mesh.cpp's passage_growth). */
  float grow_widen, grow_deepen;
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
  float rim_min_radius;    /* surface noise narrows no portal's rim below this radius (metres) */
  float rim_softness;      /* metres over which that limit eases in */
  float passage_roundness; /* roundness of small rooms with two portals */
  /* Near a portal's axis line the rim direction turns through a whole circle within a few
   * triangles; within this distance of it (metres, at most half the portal's radius) the rim
   * point the spline starts from is pulled towards the disc centre, so the patch there is not
   * spread round the whole rim and turned over (BENCHMARKS "Folded triangles"). 0: off. */
  float axis_fade;
  /* Big rooms (big_amplitude != 0) keep their sphere beyond this height above every portal
   * plane (metres), blending into the spline tube below it: halls keep their volume. */
  float keep_distance;
  /* ... and their noise is softly held from pushing the wall more than wall_allow metres
   * outside the sphere (neighbouring spheres keep the layout's wall clearance), easing in over
   * wall_softness metres, which also rounds the join of a floor and its walls. */
  float wall_allow, wall_softness;
  /* A room's floor (GrottoRoom::has_floor) undulates by floor_amplitude metres of noise at
   * floor_frequency cycles per metre; the wall rests on it (sediment fills the bowl). It fades
   * out within keep_distance of a portal plane. */
  float floor_amplitude, floor_frequency;
  float pad[2];
} GrottoShape;

/* Triples, component by component in a fixed order (a + b is a.x + b.x, ...). */
GROTTO_FN gfloat3 grotto_v3(gfloat x, gfloat y, gfloat z) {
  gfloat3 r;
  r.x = x;
  r.y = y;
  r.z = z;
  return r;
}
GROTTO_FN gfloat3 grotto_add(gfloat3 a, gfloat3 b) {
  return grotto_v3(a.x + b.x, a.y + b.y, a.z + b.z);
}
GROTTO_FN gfloat3 grotto_sub(gfloat3 a, gfloat3 b) {
  return grotto_v3(a.x - b.x, a.y - b.y, a.z - b.z);
}
GROTTO_FN gfloat3 grotto_neg(gfloat3 a) {
  return grotto_v3(-a.x, -a.y, -a.z);
}
GROTTO_FN gfloat3 grotto_scale(gfloat3 a, gfloat s) {
  return grotto_v3(a.x * s, a.y * s, a.z * s);
}
GROTTO_FN gfloat3 grotto_div(gfloat3 a, gfloat s) {
  return grotto_v3(a.x / s, a.y / s, a.z / s);
}
GROTTO_FN gfloat3 grotto_select3(gmask c, gfloat3 a, gfloat3 b) {
  return grotto_v3(c ? a.x : b.x, c ? a.y : b.y, c ? a.z : b.z);
}
GROTTO_FN gfloat grotto_dot(gfloat3 a, gfloat3 b) {
  return a.x * b.x + a.y * b.y + a.z * b.z;
}
GROTTO_FN gfloat grotto_length(gfloat3 a) {
  return grotto_sqrt(grotto_dot(a, a));
}
GROTTO_FN gfloat grotto_clamp01(gfloat x) {
  return x < 0.0f ? 0.0f : (x > 1.0f ? 1.0f : x);
}
GROTTO_FN gfloat grotto_smooth(gfloat x) {
  x = grotto_clamp01(x);
  return x * x * (3.0f - 2.0f * x);
}
GROTTO_FN gfloat3 grotto_portal_centre(GROTTO_CONSTANT const GrottoPortal* p) {
  return grotto_v3(p->cx, p->cy, p->cz);
}
GROTTO_FN gfloat3 grotto_portal_normal(GROTTO_CONSTANT const GrottoPortal* p) {
  return grotto_v3(p->nx, p->ny, p->nz);
}

/* Improved Perlin noise (Perlin 2002) with the permutation table replaced by an integer hash of
 * the lattice point and the world's noise seed. The table's chained lookups become gathers in
 * SIMD lanes (an extract, a load and an insert per lane: a third of the float8 kernel's time);
 * the hash is multiplies, shifts and xors that every lane does at once, and a shader can compute
 * it too. In [-1, 1] roughly. */
GROTTO_FN gfloat grotto_grad(guint h, gfloat x, gfloat y, gfloat z) {
  guint k = h >> 28; /* the hash's best-mixed bits pick one of Perlin's 12 (+4) gradients */
  gfloat u = k < 8u ? x : y;
  gfloat v = k < 4u ? y : (k == 12u || k == 14u ? x : z);
  return ((k & 1u) != 0u ? -u : u) + ((k & 2u) != 0u ? -v : v);
}
/* The lattice point's hash from the three pre-multiplied coordinates: one xor-shift-multiply
 * round (grotto_grad reads only the top bits, which the multiply mixes from all the others). */
GROTTO_FN guint grotto_lattice_hash(guint hx, guint hy, guint hz) {
  guint h = hx ^ hy ^ hz;
  return (h ^ (h >> 16)) * 0x7feb352du;
}
GROTTO_FN gfloat grotto_fade(gfloat t) {
  return t * t * t * (t * (t * 6.0f - 15.0f) + 10.0f);
}
GROTTO_FN gfloat grotto_lerp(gfloat t, gfloat a, gfloat b) {
  return a + t * (b - a);
}

GROTTO_FN gfloat grotto_noise(uint seed, gfloat x, gfloat y, gfloat z) {
  gfloat fx = grotto_floor(x), fy = grotto_floor(y), fz = grotto_floor(z);
  /* Wrap to a 256-cell period, as Perlin's table does; floats keep integers exact well beyond. */
  guint X = GROTTO_WRAP256(fx), Y = GROTTO_WRAP256(fy), Z = GROTTO_WRAP256(fz);
  x -= fx;
  y -= fy;
  z -= fz;
  gfloat u = grotto_fade(x), v = grotto_fade(y), w = grotto_fade(z);
  /* Each coordinate and its successor (modulo the period), times an odd constant per axis. */
  guint x0 = (X * 0x8da6b343u) ^ seed, x1 = (((X + 1u) & 255u) * 0x8da6b343u) ^ seed;
  guint y0 = Y * 0xd8163841u, y1 = ((Y + 1u) & 255u) * 0xd8163841u;
  guint z0 = Z * 0xcb1ab31fu, z1 = ((Z + 1u) & 255u) * 0xcb1ab31fu;
  gfloat xm = x - 1.0f, ym = y - 1.0f, zm = z - 1.0f;
  return grotto_lerp(
      w,
      grotto_lerp(v,
                  grotto_lerp(u, grotto_grad(grotto_lattice_hash(x0, y0, z0), x, y, z),
                              grotto_grad(grotto_lattice_hash(x1, y0, z0), xm, y, z)),
                  grotto_lerp(u, grotto_grad(grotto_lattice_hash(x0, y1, z0), x, ym, z),
                              grotto_grad(grotto_lattice_hash(x1, y1, z0), xm, ym, z))),
      grotto_lerp(v,
                  grotto_lerp(u, grotto_grad(grotto_lattice_hash(x0, y0, z1), x, y, zm),
                              grotto_grad(grotto_lattice_hash(x1, y0, z1), xm, y, zm)),
                  grotto_lerp(u, grotto_grad(grotto_lattice_hash(x0, y1, z1), x, ym, zm),
                              grotto_grad(grotto_lattice_hash(x1, y1, z1), xm, ym, zm))));
}

GROTTO_FN gfloat grotto_noise3(uint seed, gfloat3 p, float f) {
  return grotto_noise(seed, p.x * f, p.y * f, p.z * f);
}

/* The portal's section along the unit in-plane direction u, in radii: an ellipse (its height along
 * the section's up), and below the centre, where there is one, a slot with a flat floor joined to
 * it by a smooth maximum (GROTTO_SECTION_SOFTNESS radii). The section's axes come from the
 * canonical basis, so both rooms of a portal draw the same shape. */
#define GROTTO_SECTION_SOFTNESS 0.6f
GROTTO_FN gfloat grotto_section(GROTTO_CONSTANT const GrottoPortal* p, gfloat3 u) {
  float ux = p->up_c * p->e1x + p->up_s * p->e2x;
  float uy = p->up_c * p->e1y + p->up_s * p->e2y;
  float uz = p->up_c * p->e1z + p->up_s * p->e2z;
  float ax = p->up_c * p->e2x - p->up_s * p->e1x;
  float ay = p->up_c * p->e2y - p->up_s * p->e1y;
  float az = p->up_c * p->e2z - p->up_s * p->e1z;
  gfloat b = u.x * ux + u.y * uy + u.z * uz; /* along the height */
  gfloat a = u.x * ax + u.y * ay + u.z * az; /* across */
  gfloat aw = a / p->half_w, bh = b / p->half_h;
  gfloat r = 1.0f / grotto_sqrt(aw * aw + bh * bh);
  if (p->slot_depth > 0.0f) {
    /* A ray downwards leaves the slot through its floor or through a side, whichever first. */
    gfloat side = a < 0.0f ? -a : a, down = -b;
    gfloat to_floor = p->slot_depth / (down > 1e-6f ? down : 1e-6f);
    gfloat to_side = p->slot_width / (side > 1e-6f ? side : 1e-6f);
    gfloat slot = to_floor < to_side ? to_floor : to_side;
    slot = down > 0.0f ? slot : 0.0f;
    gfloat gap = r - slot;
    r = 0.5f *
        (r + slot + grotto_sqrt(gap * gap + GROTTO_SECTION_SOFTNESS * GROTTO_SECTION_SOFTNESS));
  }
  return r;
}

/* Thesis §3.1.6: the portal's radius varies with noise sampled on the rim, so rims are irregular;
 * the passage's section shapes it. u is the unit in-plane direction from the disc centre; w0 the
 * room origin in noise space. */
GROTTO_FN gfloat grotto_rim_radius(uint seed, GROTTO_CONSTANT const GrottoPortal* p,
                                   GROTTO_CONSTANT const GrottoShape* s, gfloat3 w0, gfloat3 u) {
  gfloat3 on_rim = grotto_add(grotto_add(w0, grotto_portal_centre(p)), grotto_scale(u, p->radius));
  return p->radius * (1.0f + s->rim_amplitude * grotto_noise3(seed, on_rim, s->rim_frequency)) *
         grotto_section(p, u);
}

/* Thesis §3.1.6: the surface octaves at noise-space point wp, metres along the outward direction.
 */
GROTTO_FN gfloat grotto_surface_noise(uint seed, GROTTO_CONSTANT const GrottoShape* s, gfloat3 wp) {
  gfloat d = GROTTO_SPLAT(0.0f);
  for (uint k = 0; k < s->octaves; ++k) {
    d = d + s->amplitude[k] * grotto_noise3(seed, wp, s->frequency[k]);
  }
  return d;
}

/* The surface noise d where the wall meets a portal of this radius: the same noise, so the wall
 * keeps its roughness up to the rim instead of smoothing into a collar, but softly held from
 * narrowing the irregular rim below rim_min_radius (a player must still fit through). A smooth
 * maximum of d and -allow, exact when d is well above -allow. The canonical rim (mesh/rim.cpp)
 * moves by this much, so both rooms of a portal meet on it. */
GROTTO_FN gfloat grotto_rim_noise(GROTTO_CONSTANT const GrottoShape* s, float portal_radius,
                                  gfloat d) {
  float allow = portal_radius * (1.0f - s->rim_amplitude) - s->rim_min_radius;
  allow = allow > 0.0f ? allow : 0.0f;
  gfloat x = d + allow;
  return 0.5f * (x + grotto_sqrt(x * x + s->rim_softness * s->rim_softness)) - allow;
}

/* The unit in-plane direction from a portal's centre towards the point nearest to v; *axis
 * receives v's distance from the portal's axis line. */
GROTTO_FN gfloat3 grotto_rim_direction(GROTTO_CONSTANT const GrottoPortal* p, gfloat3 v,
                                       gfloat* axis) {
  gfloat3 n = grotto_portal_normal(p);
  gfloat3 rel = grotto_sub(v, grotto_portal_centre(p));
  gfloat3 in_plane = grotto_sub(rel, grotto_scale(n, grotto_dot(rel, n)));
  gfloat len = grotto_length(in_plane);
  *axis = len;
  return grotto_select3(len < 1e-6f, grotto_v3(p->e1x, p->e1y, p->e1z), grotto_div(in_plane, len));
}

/* The smallest height of p above the room's portal planes (negative: beyond a portal). */
GROTTO_FN gfloat grotto_least_height(GROTTO_CONSTANT const GrottoPortal* portals, uint n,
                                     gfloat3 p) {
  gfloat least = GROTTO_SPLAT(3.4e38f);
  for (uint i = 0; i < n; ++i) {
    GROTTO_CONSTANT const GrottoPortal* q = portals + i;
    gfloat h = -grotto_dot(grotto_sub(p, grotto_portal_centre(q)), grotto_portal_normal(q));
    least = h < least ? h : least;
  }
  return least;
}

/* Cubic Hermite basis (thesis §3.1.4: the spline between two portal rims). */
GROTTO_FN gfloat3 grotto_hermite(gfloat3 p0, gfloat3 t0, gfloat3 p1, gfloat3 t1, gfloat t) {
  gfloat t2 = t * t, t3 = t2 * t;
  gfloat h00 = 2.0f * t3 - 3.0f * t2 + 1.0f;
  gfloat h10 = t3 - 2.0f * t2 + t;
  gfloat h01 = -2.0f * t3 + 3.0f * t2;
  gfloat h11 = t3 - t2;
  return grotto_add(
      grotto_add(grotto_add(grotto_scale(p0, h00), grotto_scale(t0, h10)), grotto_scale(p1, h01)),
      grotto_scale(t1, h11));
}

/* How a passage grows between its ends (GrottoRoom::grow_widen, grow_deepen): the spline's offset
 * d from its axis at parameter t, stretched along the sections' height (the ends' up directions
 * blended) and across it, most halfway and not at all at the rims (whose slope it keeps: the
 * growth eases in). */
GROTTO_FN gfloat3 grotto_grow(GROTTO_CONSTANT const GrottoRoom* room,
                              GROTTO_CONSTANT const GrottoPortal* pi,
                              GROTTO_CONSTANT const GrottoPortal* pj, gfloat3 d, gfloat t) {
  float widen = room->grow_widen, deepen = room->grow_deepen;
  if (widen <= 0.0f && deepen <= 0.0f) return d;
  float uix = pi->up_c * pi->e1x + pi->up_s * pi->e2x;
  float uiy = pi->up_c * pi->e1y + pi->up_s * pi->e2y;
  float uiz = pi->up_c * pi->e1z + pi->up_s * pi->e2z;
  float ujx = pj->up_c * pj->e1x + pj->up_s * pj->e2x;
  float ujy = pj->up_c * pj->e1y + pj->up_s * pj->e2y;
  float ujz = pj->up_c * pj->e1z + pj->up_s * pj->e2z;
  /* The ends' ups point the same way (both from the world's up); blended along t. */
  gfloat3 up = grotto_v3(uix + (ujx - uix) * t, uiy + (ujy - uiy) * t, uiz + (ujz - uiz) * t);
  gfloat up_len = grotto_length(up);
  up = grotto_select3(up_len > 1e-6f, grotto_div(up, up_len > 1e-6f ? up_len : 1.0f),
                      grotto_v3(0.0f, 1.0f, 0.0f));
  gfloat along = grotto_dot(d, up);
  gfloat3 d_up = grotto_scale(up, along);
  gfloat3 d_across = grotto_sub(d, d_up);
  gfloat bump = grotto_smooth(4.0f * t * (1.0f - t));
  return grotto_add(grotto_scale(d_across, 1.0f + widen * bump),
                    grotto_scale(d_up, 1.0f + deepen * bump));
}

/* A hall shaped by its beds (GrottoRoom::bed_*), far from its portals (keep): where the wall
 * faces up into the rock (its outward direction `out` along the pole) it steps along the breaks
 * between packages, each package's underside a flat slab, the rise to the next one steep (a
 * ceiling that broke along its beds, not a dome); where it faces sideways, each package stands
 * back by its notch, eased over a hand's breadth at the breaks (ledges and notches). */
GROTTO_FN gfloat3 grotto_beds(GROTTO_CONSTANT const GrottoRoom* room, gfloat3 o, gfloat3 out,
                              gfloat keep, gfloat3 pos) {
  gfloat3 pole =
      grotto_v3(GROTTO_SPLAT(room->bed_nx), GROTTO_SPLAT(room->bed_ny), GROTTO_SPLAT(room->bed_nz));
  gfloat s = grotto_dot(grotto_sub(pos, o), pole);
  gfloat lo = GROTTO_SPLAT(-3.4e38f), hi = GROTTO_SPLAT(3.4e38f);
  gfloat notch = GROTTO_SPLAT(0.0f);
  float previous = 0.0f;
  for (uint i = 0; i < room->bed_count; ++i) {
    float b = room->bed_at[i];
    lo = b <= s ? GROTTO_SPLAT(b) : lo;
    hi = (b > s) & (b < hi) ? GROTTO_SPLAT(b) : hi;
    notch = notch + (room->bed_notch[i] - previous) * grotto_smooth((s - b) / 0.6f + 0.5f);
    previous = room->bed_notch[i];
  }
  /* Between two breaks: flat at the lower one, rising steeply near the upper (x^4). */
  gmask between = (lo > -1e38f) & (hi < 1e38f);
  gfloat gap = between ? hi - lo : GROTTO_SPLAT(1.0f);
  gfloat x = between ? (s - lo) / gap : GROTTO_SPLAT(0.0f);
  gfloat x2 = x * x;
  gfloat drop = gap * (x - x2 * x2); /* s - the stepped s, >= 0 */
  gfloat up = grotto_dot(out, pole);
  gfloat ceiling = grotto_smooth((up - 0.35f) / 0.4f) * keep * room->bed_step;
  gfloat side = (1.0f - grotto_smooth(((up < 0.0f ? -up : up) - 0.3f) / 0.4f)) * keep;
  pos = grotto_sub(pos, grotto_scale(pole, drop * ceiling));
  /* Set back across the wall: the outward direction without its part along the pole. */
  gfloat3 across = grotto_sub(out, grotto_scale(pole, up));
  return grotto_sub(pos, grotto_scale(across, notch * side));
}

/* Deforms donor-sphere vertices (unit directions dir, one per lane) of a room. Returns the
 * positions in the room frame; *clearance receives the smallest distance to a portal plane on the
 * room's side (negative when the vertex ended beyond a portal: it will be removed). */
GROTTO_FN gfloat3 grotto_deform_vertex(uint seed, GROTTO_CONSTANT const GrottoShape* s,
                                       GROTTO_CONSTANT const GrottoRoom* room,
                                       GROTTO_CONSTANT const GrottoPortal* portals, gfloat3 dir,
                                       gfloat* clearance) {
  gfloat3 o = grotto_v3(room->ox, room->oy, room->oz);
  gfloat3 w0 = grotto_v3(room->wx, room->wy, room->wz);
  gfloat3 v = grotto_add(o, grotto_scale(dir, room->radius));
  uint n = room->portal_count;

  /* Per portal: the vertex's height above the plane (room side positive), its rim point with
   * irregular radius, and the plain rim point on the smooth disc. */
  gfloat height[GROTTO_MAX_PORTALS];
  gfloat3 rim[GROTTO_MAX_PORTALS];
  gfloat3 rim_dir[GROTTO_MAX_PORTALS];
  gfloat3 spline_rim[GROTTO_MAX_PORTALS]; /* rim, pulled in near the axis line (axis_fade) */
  /* Big rooms keep their sphere (below) and need no splines. */
  const int big = room->big_amplitude != 0.0f && s->keep_distance > 0.0f;
  for (uint i = 0; i < n; ++i) {
    GROTTO_CONSTANT const GrottoPortal* p = portals + i;
    gfloat3 c = grotto_portal_centre(p);
    height[i] = -grotto_dot(grotto_sub(v, c), grotto_portal_normal(p));
    gfloat axis_distance;
    rim_dir[i] = grotto_rim_direction(p, v, &axis_distance);
    rim[i] = grotto_add(c, grotto_scale(rim_dir[i], grotto_rim_radius(seed, p, s, w0, rim_dir[i])));
    spline_rim[i] = rim[i];
    float fade = s->axis_fade < 0.5f * p->radius ? s->axis_fade : 0.5f * p->radius;
    if (!big && fade > 0.0f) {
      gfloat pulled =
          grotto_smooth(axis_distance / fade); /* the rim itself, bit for bit, beyond the fade */
      spline_rim[i] = grotto_select3(
          axis_distance < fade, grotto_add(c, grotto_scale(grotto_sub(rim[i], c), pulled)), rim[i]);
    }
  }

  /* A big room keeps its sphere away from its portals. Near portal i the wall turns into a collar:
   * the irregular rim extruded straight into the room, as high as the vertex is far from the
   * circle where the sphere meets the plane, blended into the sphere within keep_distance of
   * that circle. Along each meridian both the collar and the blend move away from the axis
   * monotonically, so the blend folds no wall over; the collar leaves the plane square, so the
   * cut band stays narrow (the sphere alone meets a small portal at a grazing angle: the band
   * around it was metres wide and the holes of two portals ran into each other). The thesis's
   * spline tubes between small portals left a hall two thirds of its radius and folded where a
   * wide sphere was pulled onto them. Noise moves the wall away from the sphere's centre, which
   * lies on every portal's axis line, turned into a portal's plane near it (below), so noise
   * never moves the wall across a plane. keep: 1 beyond keep_distance from every portal's
   * circle, for the wall's hold and the floor. */
  gfloat3 smooth_pos, axis;
  gfloat nearest, keep;
  if (big) {
    gfloat3 to_collars = grotto_v3(0.0f, 0.0f, 0.0f);
    gfloat weight = GROTTO_SPLAT(0.0f), least_up = GROTTO_SPLAT(3.4e38f);
    for (uint i = 0; i < n; ++i) {
      GROTTO_CONSTANT const GrottoPortal* p = portals + i;
      gfloat3 nrm = grotto_portal_normal(p);
      /* The collar's height is the vertex's distance from the portal's plain circle (where the
       * sphere meets the plane), so vertices keep their spacing up the collar. */
      gfloat3 plain = grotto_add(grotto_portal_centre(p), grotto_scale(rim_dir[i], p->radius));
      gfloat up = grotto_length(grotto_sub(v, plain));
      up = height[i] > 0.0f ? up : 0.0f;
      gfloat3 collar = grotto_sub(rim[i], grotto_scale(nrm, up));
      gfloat w = 1.0f - grotto_smooth(up / s->keep_distance);
      to_collars = grotto_add(to_collars, grotto_scale(grotto_sub(collar, v), w));
      weight = weight + w;
      least_up = up < least_up ? up : least_up;
    }
    smooth_pos = grotto_add(v, grotto_div(to_collars, weight > 1.0f ? weight : 1.0f));
    axis = o; /* on every portal's axis line: turned into the planes below */
    nearest = grotto_least_height(portals, n, smooth_pos);
    keep = grotto_smooth(least_up / s->keep_distance);
  } else {
    /* Thesis §3.1.4-3.1.5: project onto the Hermite spline between every pair of portal rims, the
     * parameter from the heights above the two planes, and blend the pairs weighted by how close
     * each projection is to the vertex. The axis (the same spline through the disc centres) gives
     * the outward direction for noise. */
    gfloat3 sum = grotto_v3(0.0f, 0.0f, 0.0f), axis_sum = grotto_v3(0.0f, 0.0f, 0.0f);
    gfloat weight_sum = GROTTO_SPLAT(0.0f);
    for (uint i = 0; i < n; ++i) {
      for (uint j = i + 1u; j < n; ++j) {
        GROTTO_CONSTANT const GrottoPortal* pi = portals + i;
        GROTTO_CONSTANT const GrottoPortal* pj = portals + j;
        gfloat hi = height[i] > 0.0f ? height[i] : 0.0f;
        gfloat hj = height[j] > 0.0f ? height[j] : 0.0f;
        gfloat t = hi + hj > 0.0f ? hi / (hi + hj) : 0.5f;
        gfloat3 ni = grotto_portal_normal(pi), nj = grotto_portal_normal(pj);
        gfloat span = grotto_length(grotto_sub(spline_rim[j], spline_rim[i])) * s->tension;
        gfloat3 h = grotto_hermite(spline_rim[i], grotto_scale(grotto_neg(ni), span), spline_rim[j],
                                   grotto_scale(nj, span), t);
        gfloat3 ci = grotto_portal_centre(pi), cj = grotto_portal_centre(pj);
        gfloat axis_span = grotto_length(grotto_sub(cj, ci)) * s->tension;
        gfloat3 a = grotto_hermite(ci, grotto_scale(grotto_neg(ni), axis_span), cj,
                                   grotto_scale(nj, axis_span), t);
        /* A passage (two portals) grows between its ends; a junction's pairs do not (a pair's
         * growth would push its wall across a third portal's plane). */
        if (n == 2u) h = grotto_add(a, grotto_grow(room, pi, pj, grotto_sub(h, a), t));
        gfloat3 d = grotto_sub(h, v);
        gfloat wgt = 1.0f / (grotto_dot(d, d) + 1e-4f);
        sum = grotto_add(sum, grotto_scale(h, wgt));
        axis_sum = grotto_add(axis_sum, grotto_scale(a, wgt));
        weight_sum = weight_sum + wgt;
      }
    }
    /* A dead end (one portal): the sphere itself, bent onto the irregular rim near the portal. */
    gfloat3 dead_end = v;
    if (n == 1u) {
      gfloat3 plain =
          grotto_add(grotto_portal_centre(portals), grotto_scale(rim_dir[0], portals->radius));
      gfloat pull = 1.0f - grotto_smooth(height[0] / (0.5f * room->radius));
      dead_end = grotto_add(v, grotto_scale(grotto_sub(rim[0], plain), pull));
    }
    /* Its axis: the portal's near the portal (noise then moves the wall within the portal plane,
     * where the rim moves), the sphere's centre deeper in. */
    gfloat3 dead_axis = o;
    if (n == 1u) {
      gfloat h0 = -grotto_dot(grotto_sub(dead_end, grotto_portal_centre(portals)),
                              grotto_portal_normal(portals));
      gfloat3 on_axis = grotto_sub(grotto_portal_centre(portals),
                                   grotto_scale(grotto_portal_normal(portals), h0));
      dead_axis = grotto_add(
          on_axis, grotto_scale(grotto_sub(o, on_axis), grotto_smooth(h0 / (0.5f * room->radius))));
    }
    gmask blended = weight_sum > 0.0f;
    smooth_pos = grotto_select3(blended, grotto_div(sum, weight_sum), dead_end);
    axis = grotto_select3(blended, grotto_div(axis_sum, weight_sum), dead_axis);

    /* Far from portals a room may keep some of its sphere (caverns stay round). A small room whose
     * two portals face each other across it is a straight stretch of passage and keeps less: a
     * shaft of them, each bulging out to its sphere between narrow portals, was a string of beads,
     * puckered at every portal. A bent one keeps its roundness: its tube would leave the sphere's
     * centre, where players spawn and the flythrough passes, outside the wall. */
    float roundness = s->roundness;
    if (n == 2u) {
      float facing = -(portals[0].nx * portals[1].nx + portals[0].ny * portals[1].ny +
                       portals[0].nz * portals[1].nz);
      float straight = (facing - 0.5f) / 0.35f;
      straight = straight < 0.0f ? 0.0f : (straight > 1.0f ? 1.0f : straight);
      straight = straight * straight * (3.0f - 2.0f * straight);
      roundness = roundness + (s->passage_roundness - roundness) * straight;
    }
    nearest = grotto_least_height(portals, n, smooth_pos);
    keep = roundness * grotto_smooth(nearest / room->radius);
    smooth_pos = grotto_add(smooth_pos, grotto_scale(grotto_sub(v, smooth_pos), keep));
    axis = grotto_add(axis, grotto_scale(grotto_sub(o, axis), keep));
  }

  /* Thesis §3.1.6: world-space noise along the outward direction; big rooms get a low octave too,
   * faded out near portals. At a portal plane the outward direction lies in the plane and the
   * surface noise is what the canonical rim moved by (grotto_rim_noise), so the wall runs rough
   * into the rim: fading the noise to nothing there left a smooth collar around every portal,
   * two creased rings. Near any other part of a portal plane (where a bend brings the wall
   * close to a plane's extension, far from its disc) the noise still fades to nothing, so no
   * vertex crosses a plane. */
  gfloat3 out = grotto_sub(smooth_pos, axis);
  if (big) {
    for (uint i = 0; i < n; ++i) {
      GROTTO_CONSTANT const GrottoPortal* p = portals + i;
      gfloat3 nrm = grotto_portal_normal(p);
      gfloat h = -grotto_dot(grotto_sub(smooth_pos, grotto_portal_centre(p)), nrm);
      gfloat turn = 1.0f - grotto_smooth(h / s->fade_distance);
      out = grotto_sub(out, grotto_scale(nrm, grotto_dot(out, nrm) * turn));
    }
  }
  gfloat out_len = grotto_length(out);
  out = grotto_select3(out_len > 1e-6f, grotto_div(out, out_len), dir);
  gfloat3 wp = grotto_add(w0, smooth_pos);
  gfloat noise = grotto_surface_noise(seed, s, wp);
  gfloat near_sum = GROTTO_SPLAT(0.0f), rim_sum = GROTTO_SPLAT(0.0f);
  for (uint i = 0; i < n; ++i) {
    GROTTO_CONSTANT const GrottoPortal* p = portals + i;
    gfloat3 rel = grotto_sub(smooth_pos, grotto_portal_centre(p));
    gfloat h = -grotto_dot(rel, grotto_portal_normal(p));
    gfloat3 in_plane = grotto_add(rel, grotto_scale(grotto_portal_normal(p), h));
    gfloat beyond_disc = grotto_length(in_plane) - p->radius * p->reach * (1.0f + s->rim_amplitude);
    gfloat near_plane = 1.0f - grotto_smooth(h / s->fade_distance);
    gfloat on_disc = 1.0f - grotto_smooth(beyond_disc / s->fade_distance - 1.0f);
    near_sum = near_sum + near_plane;
    rim_sum = rim_sum + near_plane * on_disc * grotto_rim_noise(s, p->radius * p->narrow, noise);
  }
  gfloat rim_target = near_sum > 0.0f ? rim_sum / (near_sum > 0.0f ? near_sum : 1.0f) : 0.0f;
  gfloat fade = grotto_smooth(nearest / s->fade_distance);
  gfloat displacement = noise * fade + rim_target * (1.0f - fade);
  displacement = displacement + room->big_amplitude * grotto_noise3(seed, wp, s->big_frequency) *
                                    grotto_smooth(nearest / s->big_fade_distance);
  if (big) {
    /* Where the wall kept its sphere, hold the noise softly within wall_allow outside it (a smooth
     * minimum of the displacement and the allowance). */
    gfloat allow = (room->radius + s->wall_allow) - grotto_length(grotto_sub(smooth_pos, o));
    gfloat gap = displacement - allow;
    gfloat held = 0.5f * (displacement + allow -
                          grotto_sqrt(gap * gap + s->wall_softness * s->wall_softness));
    displacement = displacement + (held - displacement) * keep;
  }
  gfloat3 pos = grotto_add(smooth_pos, grotto_scale(out, displacement));
  if (room->has_floor != 0u) {
    /* The floor: the wall rests on an undulating plane (a smooth maximum of its height and the
     * floor's), faded out near portal planes. The noise is sampled on the floor's plane, so the
     * floor is a height field. */
    float floor_y = room->floor_y;
    float f = s->floor_frequency;
    gfloat fx = (w0.x + pos.x) * f, fz = (w0.z + pos.z) * f;
    gfloat fy = GROTTO_SPLAT((room->wy + floor_y) * f);
    gfloat target =
        floor_y + s->floor_amplitude * (grotto_noise(seed, fx, fy, fz) +
                                        0.5f * grotto_noise(seed, fz * 2.0f, fy, fx * 2.0f));
    gfloat rise = target - pos.y;
    gfloat lifted =
        pos.y + 0.5f * (rise + grotto_sqrt(rise * rise + s->wall_softness * s->wall_softness));
    pos.y = pos.y + (lifted - pos.y) * keep;
  }
  if (room->ceiling_squash > 0.0f) {
    /* The ceiling: the wall above the spring comes down onto a low dome (cave::Ceiling::lower),
     * away from portals (they open below the spring). */
    gfloat t = pos.y - room->ceiling_y;
    t = t > 0.0f ? t : 0.0f;
    float bend = room->ceiling_bend;
    gfloat ramp = t < bend ? t * t / (2.0f * bend) : t - 0.5f * bend;
    pos.y = pos.y - room->ceiling_squash * ramp * keep;
  }

  if (big && room->bed_count > 0u) pos = grotto_beds(room, o, out, keep, pos);

  *clearance = grotto_least_height(portals, n, pos);
  return pos;
}
