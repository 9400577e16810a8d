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

#include "core/common/types.h"

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

// F controls at once (the double pendulum's two torques): a ~ N(mean, cov)
// (F-dim), u_j = max_u_j (9 sin a_j + sin 3a_j) / 8. With q = [a; 3a] (2F,
// a linear map of a, singular covariance allowed) and y = [q; (sin, cos) per
// entry of q] from AugmentWithTrig (trig.h), u is a linear map of y's sin
// entries, so that
//   E[u_j] = max_u_j (9 E sin q_j + E sin q_{F+j}) / 8,
//   Cov[u] = L Cov[sin q] L^T   (L: F x 2F, L_jj = 9 max_u_j / 8, L_j,F+j = max_u_j / 8),
//   c_j    = E[du_j/da_j] = max_u_j (9 E cos q_j + 3 E cos q_{F+j}) / 8,
// and Cov(a, u) = cov diag(c) (Stein's lemma; u_j depends on a_j only).
// F = 1 gives GSat's numbers (to round-off; GSat stays the one-control path).
struct JointSatMoments {
  Vector mean;  // F, E[u]
  Matrix cov;   // F x F, Cov[u], symmetric
  Vector c;     // F, E[du_j/da_j]
};

// mean (F), cov (F x F symmetric PSD), max_u (F, > 0).
void GSatJoint(const Vector& mean, const Matrix& cov, const Vector& max_u, JointSatMoments* out);

// Reverse mode: from the adjoints of out.mean (F), out.cov (F x F, every
// entry its own output) and out.c (F), ADDS the adjoints of mean and cov to
// *mean_bar (F) and *cov_bar (F x F), which must be sized.
void GSatJointBackward(const Vector& mean, const Matrix& cov, const Vector& max_u,
                       const Vector& u_mean_bar, const Matrix& u_cov_bar, const Vector& c_bar,
                       Vector* mean_bar, Matrix* cov_bar);

}  // namespace totalgrad::pilco

#endif  // TOTALGRAD_CORE_PILCO_SATURATION_H_
