/* The detail channels (roughness and mineral: world-space noise fields sampled at each vertex of a
 * finished room mesh, so the vertices two rooms share at a portal agree) of many rooms' vertices in
 * one launch, one vertex per work item; bit-identical to mesh::detail_channels. Built after
 * deform_prelude.cl (GROTTO_LANES 1) and deform_core.h, with GROTTO_NOISE_PERIOD (mesh::
 * kNoisePeriod, a power of two) defined by the host. A work item finds its room by binary search
 * over the rooms' first vertices, as the deformation does. The world position is formed and
 * wrapped into the noise period in double precision, exactly as MeshContext::noise_position does
 * (hence cl_khr_fp64). */
#pragma OPENCL EXTENSION cl_khr_fp64 : enable

/* v modulo the period in [0, period), a zero keeping v's sign: mesh/context.cpp's wrap(). */
double grotto_wrap_period(double v) {
  double q = v * (1.0 / GROTTO_NOISE_PERIOD);
  double f = q;
  if (fabs(q) < 4611686018427387904.0) { /* 2^62 */
    f = (double)(long)q;
    if (f > q) f -= 1.0;
  }
  double r = v - f * GROTTO_NOISE_PERIOD;
  return r == 0.0 ? copysign(0.0, v) : r;
}

__kernel void grotto_detail_channels(__global const double* origins,
                                     __global const uint* first_vertex, __global const uint* seeds,
                                     uint room_count, __global const float* positions,
                                     __global float* roughness, __global float* mineral,
                                     uint vertex_count, float f_rough, float f_rough3,
                                     float f_mineral) {
  uint v = get_global_id(0);
  if (v >= vertex_count) return;
  uint lo = 0, hi = room_count - 1;
  while (lo < hi) {
    const uint mid = (lo + hi + 1) / 2;
    if (first_vertex[mid] <= v) {
      lo = mid;
    } else {
      hi = mid - 1;
    }
  }
  gfloat3 w;
  w.x = (float)grotto_wrap_period(origins[3 * lo] + (double)positions[3 * v]);
  w.y = (float)grotto_wrap_period(origins[3 * lo + 1] + (double)positions[3 * v + 1]);
  w.z = (float)grotto_wrap_period(origins[3 * lo + 2] + (double)positions[3 * v + 2]);
  const uint seed = seeds[lo];
  gfloat r = grotto_noise3(seed, w, f_rough);
  gfloat r2 = grotto_noise3(seed, w, f_rough3);
  roughness[v] = grotto_clamp01(0.5f + 0.7f * r + 0.3f * r2);
  gfloat m = grotto_noise3(seed, w, f_mineral);
  mineral[v] = grotto_smooth((m - 0.2f) * 4.0f);
}
