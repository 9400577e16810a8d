// PILCO's saturation of the control under a Gaussian input (gSat,
// pilco-spec.md 3.2):
//
//   u = u_max (9 sin a + sin 3a) / 8,   a ~ N(mean, var)
//
// returns E[u], Var[u] and C = Cov(a, u) / var = E[du/da] (Stein's lemma; C is
// well defined for var = 0 too).
//
// Thread safety: free functions.
#ifndef TOTALGRAD_CORE_PILCO_SATURATION_H_
#define TOTALGRAD_CORE_PILCO_SATURATION_H_

#include <Eigen/Core>

namespace totalgrad::pilco {

struct SatMoments {
  double mean = 0;      // E[u]
  double var = 0;       // Var[u] (may be ~ -1e-16 from round-off when var -> 0)
  double c = 0;         // Cov(a, u) / Var(a) = E[du/da]
  Eigen::Vector3d AsVector() const { return {mean, var, c}; }
};

// var >= 0, max_u > 0.
SatMoments GSat(double mean, double var, double max_u);

// 3 x 2 Jacobian of GSat(...).AsVector() with respect to (mean, var).
Eigen::Matrix<double, 3, 2> Dx_GSat(double mean, double var, double max_u);

}  // namespace totalgrad::pilco

#endif  // TOTALGRAD_CORE_PILCO_SATURATION_H_
