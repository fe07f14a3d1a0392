/* The detail channels (roughness and mineral: world-space noise fields sampled at a vertex, so the
 * vertices two rooms share at a portal agree) of one vertex, bit-identical to
 * mesh::detail_channels. Built after deform_prelude.cl (GROTTO_LANES 1) and deform_core.h, with
 * GROTTO_NOISE_PERIOD (mesh::kNoisePeriod, a power of two) defined by the host, when the
 * deformation computes its vertices' channels too (deform.cl, GROTTO_CHANNELS). The world position
 * is formed and wrapped into the noise period in double precision, exactly as
 * MeshContext::noise_position does (hence cl_khr_fp64). */
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

/* The channels at origin + p. `room` holds the room's channel record: its origin in world metres
 * (x, y, z) and its world's frequencies (roughness, three times roughness, mineral), each a float
 * value held in a double. */
void grotto_detail_channels_at(__global const double* room, uint seed, gfloat3 p,
                               __global float* roughness, __global float* mineral) {
  gfloat3 w;
  w.x = (float)grotto_wrap_period(room[0] + (double)p.x);
  w.y = (float)grotto_wrap_period(room[1] + (double)p.y);
  w.z = (float)grotto_wrap_period(room[2] + (double)p.z);
  gfloat r = grotto_noise3(seed, w, (float)room[3]);
  gfloat r2 = grotto_noise3(seed, w, (float)room[4]);
  *roughness = grotto_clamp01(0.5f + 0.7f * r + 0.3f * r2);
  gfloat m = grotto_noise3(seed, w, (float)room[5]);
  *mineral = grotto_smooth((m - 0.2f) * 4.0f);
}
