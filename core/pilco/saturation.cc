#include "core/pilco/saturation.h"

#include <cmath>

namespace totalgrad::pilco {

// With s1 = sin a, s3 = sin 3a, u = U (9/8 s1 + 1/8 s3):
//   Var[u] = U^2 (81/64 Var s1 + 1/64 Var s3 + 18/64 Cov(s1, s3)),
//   Var s1      = -1/2 expm1(-2v)  + e^{-v}  expm1(-v)  sin^2 m,
//   Var s3      = -1/2 expm1(-18v) + e^{-9v} expm1(-9v) sin^2 3m,
//   Cov(s1, s3) = 1/2 e^{-5v} (expm1(3v) cos 2m - expm1(-3v) cos 4m)
//               = -1/2 expm1(-3v) (e^{-2v} cos 2m + e^{-5v} cos 4m).
SatMoments GSat(double mean, double var, double max_u) {
  const double m = mean, v = var, u = max_u;
  const double e1 = std::exp(-0.5 * v), e9 = std::exp(-4.5 * v);
  SatMoments out;
  out.mean = u * (9.0 / 8.0 * e1 * std::sin(m) + 1.0 / 8.0 * e9 * std::sin(3.0 * m));
  out.c = u * (9.0 / 8.0 * e1 * std::cos(m) + 3.0 / 8.0 * e9 * std::cos(3.0 * m));
  const double s1 = std::sin(m), s3 = std::sin(3.0 * m);
  const double var1 = -0.5 * std::expm1(-2.0 * v) + std::exp(-v) * std::expm1(-v) * s1 * s1;
  const double var3 = -0.5 * std::expm1(-18.0 * v) + std::exp(-9.0 * v) * std::expm1(-9.0 * v) * s3 * s3;
  // e^{-5v} expm1(3v) is written as -e^{-2v} expm1(-3v): the same value, but
  // expm1(3v) overflows to Inf for v > 236 while e^{-5v} underflows to 0, and
  // 0 * Inf would make Var[u] NaN for a wide input distribution.
  const double cov13 = -0.5 * std::expm1(-3.0 * v) *
                       (std::exp(-2.0 * v) * std::cos(2.0 * m) + std::exp(-5.0 * v) * std::cos(4.0 * m));
  out.var = u * u * (81.0 / 64.0 * var1 + 1.0 / 64.0 * var3 + 18.0 / 64.0 * cov13);
  return out;
}

Eigen::Matrix<double, 3, 2> Dx_GSat(double mean, double var, double max_u) {
  const double m = mean, v = var, u = max_u;
  const double e1 = std::exp(-0.5 * v), e9 = std::exp(-4.5 * v);
  Eigen::Matrix<double, 3, 2> j;
  j(0, 0) = u * (9.0 / 8.0 * e1 * std::cos(m) + 3.0 / 8.0 * e9 * std::cos(3.0 * m));
  j(0, 1) = u * (-9.0 / 16.0 * e1 * std::sin(m) - 9.0 / 16.0 * e9 * std::sin(3.0 * m));
  j(2, 0) = u * (-9.0 / 8.0 * e1 * std::sin(m) - 9.0 / 8.0 * e9 * std::sin(3.0 * m));
  j(2, 1) = u * (-9.0 / 16.0 * e1 * std::cos(m) - 27.0 / 16.0 * e9 * std::cos(3.0 * m));
  const double ev = std::exp(-v), e2v = std::exp(-2.0 * v), e5v = std::exp(-5.0 * v),
               e8v = std::exp(-8.0 * v), e9v = std::exp(-9.0 * v), e18v = std::exp(-18.0 * v);
  const double s1 = std::sin(m), s3 = std::sin(3.0 * m);
  const double c2 = std::cos(2.0 * m), s2 = std::sin(2.0 * m), c4 = std::cos(4.0 * m),
               s4 = std::sin(4.0 * m), c6 = std::cos(6.0 * m), s6 = std::sin(6.0 * m);
  const double dvar1_dm = s2 * (e2v - ev);
  const double dvar1_dv = e2v * c2 + ev * s1 * s1;
  const double dvar3_dm = 3.0 * s6 * (e18v - e9v);
  const double dvar3_dv = 9.0 * e18v * c6 + 9.0 * e9v * s3 * s3;
  const double dcov_dm = 0.5 * (-2.0 * e2v * s2 + 4.0 * e8v * s4 + 2.0 * e5v * s2 - 4.0 * e5v * s4);
  const double dcov_dv = 0.5 * (-2.0 * e2v * c2 + 8.0 * e8v * c4 + 5.0 * e5v * c2 - 5.0 * e5v * c4);
  j(1, 0) = u * u * (81.0 / 64.0 * dvar1_dm + 1.0 / 64.0 * dvar3_dm + 18.0 / 64.0 * dcov_dm);
  j(1, 1) = u * u * (81.0 / 64.0 * dvar1_dv + 1.0 / 64.0 * dvar3_dv + 18.0 / 64.0 * dcov_dv);
  return j;
}

}  // namespace totalgrad::pilco
