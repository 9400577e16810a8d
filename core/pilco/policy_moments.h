// The RBF policy (core/policy/rbf_policy.h layout) under a Gaussian input:
// PILCO's congp + gp2 (mean function only) followed by gSat (conCat),
// pilco-spec.md 5.1-5.2.
//
//   a(x) = sum_k w_k exp(-1/2 sum_m (x_m - c_km)^2 / l_m^2)   (sf = 1)
//   u    = max_force (9 sin a + sin 3a) / 8
//
// Parameters, as in RbfPolicy: [centres row-major (C x E), log l (E),
// weights (C)]. The weights play the role of gp2's beta = (K + sn^2 I)^-1 y:
// PILCO's policy with pseudo-targets y is ours with w = beta.
//
// For x ~ N(m, s) (E-dim) the unsquashed output has mean a_mean, variance
// a_var (+ jitter; PILCO: 1e-6) and a_cross = s^-1 Cov(x, a) (E); after the
// saturation u_mean, u_var and u_cross = s^-1 Cov(x, u) = a_cross * E[du/da].
//
// Derivatives with respect to the length-scales use the fact that the
// moments depend on (centres, m, s) only through the scaled quantities
// centres / l, m / l, s / (l l^T): gp2 is evaluated with unit length-scales in
// scaled coordinates and the chain rule is applied to the scaling.
//
// Thread safety: free functions.
#ifndef TOTALGRAD_CORE_PILCO_POLICY_MOMENTS_H_
#define TOTALGRAD_CORE_PILCO_POLICY_MOMENTS_H_

#include "absl/status/status.h"
#include "core/common/types.h"
#include "core/pilco/saturation.h"

namespace totalgrad::pilco {

struct RbfPolicyShape {
  int num_basis = 0;      // C
  int input_dim = 0;      // E
  double max_force = 10;  // u_max > 0 (one control)
  double jitter = 1e-6;   // added to a_var (PILCO's gp2)
  // F >= 2 controls (the double pendulum): their bounds, and the weights are
  // C x F row-major (RbfPolicy's layout). Empty: one control at max_force.
  Vector max_controls;
  // F >= 2 only: one row of log length-scales per control (PILCO's gp2 with
  // per-output hyperparameters); the layout is then [centres (C x E), log l
  // (F x E row-major), weights (C x F)]. Cov(a_i, a_j) couples two different
  // Lambda (gp_moments.h), and the length-scale gradient comes from
  // PredictGaussianLengthscaleAdjoint. false: one shared row (E).
  bool lengthscale_per_control = false;
  int num_controls() const { return max_controls.size() >= 2 ? static_cast<int>(max_controls.size()) : 1; }
  int num_lengthscale_rows() const {
    return lengthscale_per_control && num_controls() >= 2 ? num_controls() : 1;
  }
  int num_parameters() const {
    return num_basis * input_dim + num_lengthscale_rows() * input_dim + num_basis * num_controls();
  }
};

struct PolicyMoments {
  double a_mean = 0, a_var = 0;
  Vector a_cross;  // E
  SatMoments sat;  // E[u], Var[u], E[du/da] (sat.mean, sat.var, sat.c)
  Vector u_cross;  // E, a_cross * sat.c
};

// F >= 2 controls (shape.max_controls): the unsquashed outputs a (F) share
// the basis functions and length-scales, one weight column each, so that
// gp2 has F outputs; a_cov (F x F, + jitter on the diagonal) couples them,
// and the saturation is GSatJoint's.
struct MultiPolicyMoments {
  Vector a_mean;         // F
  Matrix a_cov;          // F x F
  Matrix a_cross;        // E x F, s^-1 Cov(x, a)
  JointSatMoments sat;   // E[u] (F), Cov[u] (F x F), c = E[du_j/da_j] (F)
  Matrix u_cross;        // E x F, s^-1 Cov(x, u) = a_cross diag(c)
};

// Errors: as PredictGaussian. CHECK-fails unless shape.num_controls() >= 2.
absl::Status MultiPolicyAtGaussian(const RbfPolicyShape& shape, const Vector& params,
                                   const Vector& m, const Matrix& s, MultiPolicyMoments* out);

// Reverse mode from the adjoints of u's mean (F), covariance (F x F, every
// entry its own output) and u_cross (E x F): OVERWRITES *m_bar (E) and
// *s_bar (E x E, symmetric) and ADDS to *params_bar (may be null).
absl::Status MultiPolicyAtGaussianBackward(const RbfPolicyShape& shape, const Vector& params,
                                           const Vector& m, const Matrix& s,
                                           const Vector& u_mean_bar, const Matrix& u_cov_bar,
                                           const Matrix& u_cross_bar, Vector* m_bar, Matrix* s_bar,
                                           Vector* params_bar);

// Errors: as PredictGaussian (non-finite or non-PSD input covariance).
// One control (CHECK-fails on shape.num_controls() >= 2).
absl::Status PolicyAtGaussian(const RbfPolicyShape& shape, const Vector& params, const Vector& m,
                              const Matrix& s, PolicyMoments* out);

// Reverse mode through the unsquashed output only: given adjoints of a_mean,
// a_var and a_cross, OVERWRITES *m_bar (E) and *s_bar (E x E, symmetric) and
// ADDS to *params_bar (num_parameters(); may be null).
absl::Status UnsquashedPolicyBackward(const RbfPolicyShape& shape, const Vector& params,
                                      const Vector& m, const Matrix& s, double a_mean_bar,
                                      double a_var_bar, const Vector& a_cross_bar, Vector* m_bar,
                                      Matrix* s_bar, Vector* params_bar);

// Reverse mode through the squashed policy: adjoints of u_mean, u_var and
// u_cross (E). Same outputs as UnsquashedPolicyBackward.
absl::Status PolicyAtGaussianBackward(const RbfPolicyShape& shape, const Vector& params,
                                      const Vector& m, const Matrix& s, double u_mean_bar,
                                      double u_var_bar, const Vector& u_cross_bar, Vector* m_bar,
                                      Matrix* s_bar, Vector* params_bar);

// PILCO's own policy parameterisation (congp): pseudo-targets y instead of
// weights, w = (K_cc + sn^2 I)^-1 y with K_cc,kl = exp(-1/2 sum_m (c_km -
// c_lm)^2 / l_m^2) (sf = 1) and sn = 0.01, both fixed by congp.
inline constexpr double kCongpNoiseVar = 1e-4;

// pilco_params = [centres row-major, log l, pseudo-targets (C x F row-major)];
// writes *params = [centres, log l, weights (C x F)] (RbfPolicy's layout),
// W = (K_cc + sn^2 I)^-1 Y column by column. Errors:
// FailedPrecondition if K_cc + sn^2 I cannot be factorised (e.g. non-finite
// numbers).
absl::Status PseudoTargetsToWeights(const RbfPolicyShape& shape, const Vector& pilco_params,
                                    Vector* params);

// The inverse of PseudoTargetsToWeights: from params = [centres, log l,
// weights] writes *pilco_params = [centres, log l, y] with y = (K_cc +
// sn^2 I) w. Errors as PseudoTargetsToWeights.
absl::Status WeightsToPseudoTargets(const RbfPolicyShape& shape, const Vector& params,
                                    Vector* pilco_params);

// Chain rule through PseudoTargetsToWeights: from params_bar (the gradient
// with respect to [centres, log l, weights]) OVERWRITES *pilco_params_bar
// with the gradient with respect to [centres, log l, pseudo-targets], i.e.
// what PILCO's value.m returns for inputs, hyp(1..E) and targets.
absl::Status PseudoTargetsBackward(const RbfPolicyShape& shape, const Vector& pilco_params,
                                   const Vector& params_bar, Vector* pilco_params_bar);

}  // namespace totalgrad::pilco

#endif  // TOTALGRAD_CORE_PILCO_POLICY_MOMENTS_H_
