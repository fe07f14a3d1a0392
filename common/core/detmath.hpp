// Deterministic transcendental functions built from +, -, *, / only, for values that two
// servers must compute bit-identically (portal rim loops). libm's sin and cos may differ in the
// last bit between versions and platforms; these do not.
#pragma once

namespace grotto::detmath {

inline constexpr double kPi = 3.14159265358979323846;

// sin and cos of x in [-pi, pi] by Taylor series to degree 23 (error below 1e-15 there).
inline void sincos(double x, double& s, double& c) {
  double x2 = x * x;
  double term_s = x, term_c = 1.0;
  s = x;
  c = 1.0;
  for (int k = 1; k <= 11; ++k) {
    term_s = -term_s * x2 / ((2 * k) * (2 * k + 1));
    term_c = -term_c * x2 / ((2 * k - 1) * (2 * k));
    s += term_s;
    c += term_c;
  }
}

// A monotonic stand-in for atan2 in [0, 4): orders points by angle around an axis without libm.
inline double pseudo_angle(double x, double y) {
  double ax = x < 0 ? -x : x, ay = y < 0 ? -y : y;
  double sum = ax + ay;
  if (sum == 0) return 0;
  double p = y / sum;  // in [-1, 1]
  return x < 0 ? 2.0 - p : (y < 0 ? 4.0 + p : p);
}

}  // namespace grotto::detmath
