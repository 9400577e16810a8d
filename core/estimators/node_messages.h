// The messages of the backward passes (paper section 3, Algorithm 1).
//
// Every transition node t (x_t -> x_{t+1}) has, per particle i, distribution
// parameters zeta_i = (mu_i, v_i): x_{t+1}^i ~ N(mu_i, diag v_i) with
// mu_i = x_t^i + mean(z_t^i), v_i = var(z_t^i), z_t^i = [x_t^i, u_t^i].
// A backward pass sends each node a cotangent on zeta (dG/dzeta, G the cost
// still to come). How that cotangent is estimated is the estimator's choice:
// pathwise (RP, from dG/dx_{t+1}), a jump (LR, BIW-LR, DEL: directly from the
// sampled costs), or their variance-weighted combination (TP). Whatever its
// origin, the cotangent crosses the node the same way (TransitionVjp): into
// the model's inputs, i.e. into the force (then through the policy to theta
// and to x_t) and directly into x_t.
//
// Thread safety: functions are re-entrant.
#ifndef TOTALGRAD_CORE_ESTIMATORS_NODE_MESSAGES_H_
#define TOTALGRAD_CORE_ESTIMATORS_NODE_MESSAGES_H_

#include "core/common/thread_pool.h"
#include "core/common/types.h"
#include "core/estimators/rollout.h"

namespace totalgrad::estimators {

// Cotangent on the distribution parameters of every particle of one node.
struct ZetaCotangent {
  RowMatrix mean;      // P x S, dG/dmu_i
  RowMatrix variance;  // P x S, dG/dv_i
};

// The RP (pathwise) cotangent from gamma_i = dG/dx_{t+1}^i (P x S) through
// x_{t+1} = mu + sqrt(v) eps with eps held fixed:
//   mean_bar = gamma,   var_bar = gamma eps / (2 sqrt(v))   (0 where v == 0).
// On a resampled step gamma must already be the cotangent on the particles
// before resampling (StepResampler::Backward).
void RpZetaCotangent(const StepRecord& step, const RowMatrix& gamma, ZetaCotangent* out);

// Crosses node t without its policy: with
//   z_bar_i = dmean/dz_i^T mean_bar_i + dvar/dz_i^T var_bar_i   (E = S + F)
// force_bar (P F, particle-major) = the control entries of z_bar; state_bar
// (P x S, overwritten, may be null) = mean_bar + the state entries of z_bar
// (mu = x_t + mean(z)). The caller adds the policy's part, sum_j
// force_bar_ij du_ij/dx_t^i, and the parameter contribution sum_j
// force_bar_ij du_ij/dtheta. Needs a rollout recorded with Jacobians.
// `pool` (may be null) runs fixed particle blocks; same bits for any size.
void TransitionVjp(const StepRecord& step, const ZetaCotangent& cotangent, Vector* force_bar,
                   RowMatrix* state_bar, ThreadPool* pool = nullptr);

// Sum over the rows r_i (P x n) of |r_i - mean r|^2 / (P - 1), the trace of
// the sample covariance, kept as scale^2 * normalized so that exploding
// gradients (|r| ~ 1e200) still give a usable ratio. P = 1 gives 0.
struct TraceVariance {
  double scale = 0;       // largest |deviation| entry
  double normalized = 0;  // sum of (deviation / scale)^2 / (P - 1)
  bool non_finite = false;  // some row entry was Inf or NaN
  bool zero() const { return !non_finite && (scale == 0 || normalized == 0); }
  double value() const;   // scale^2 * normalized (Inf when that overflows or non_finite)
};
TraceVariance RowTraceVariance(const RowMatrix& rows);
// The same for the rows r_i = factor_i * rows_i (factor: P), without forming
// them: what TP needs for each branch's per-particle gradients, which share
// the policy's Jacobian rows and differ by a scalar per particle. `mean` is
// scratch (n entries, resized).
TraceVariance ScaledRowTraceVariance(const Vector& factor, const RowMatrix& rows,
                                     Vector* mean);
// Both of TP's branches at once: *a and *b are exactly (bit for bit)
// ScaledRowTraceVariance(factor_a, rows, .) and (factor_b, rows, .), with
// each pass over `rows` (P x n, read three times per branch) shared by the
// two; the rows are the step's largest operand, so this halves the memory
// traffic of the combination weight. `mean_a`, `mean_b` are scratch.
void ScaledRowTraceVariances(const Vector& factor_a, const Vector& factor_b,
                             const RowMatrix& rows, Vector* mean_a, Vector* mean_b,
                             TraceVariance* a, TraceVariance* b);

// Total propagation's weight on the jump (LR) estimate of one node,
// k_LR = 1 / (1 + var_LR / var_RP), with its limits made explicit:
//   both zero -> 1/2; var_RP zero -> 0; var_LR zero -> 1;
//   var_RP non-finite (Inf, NaN) -> 1; var_LR non-finite -> 0;
//   both non-finite -> 1/2.
// Always in [0, 1], never NaN.
double CombinationWeight(const TraceVariance& rp, const TraceVariance& lr);
// The same rule on plain variances (>= 0, Inf or NaN).
double CombinationWeight(double var_rp, double var_lr);

}  // namespace totalgrad::estimators

#endif  // TOTALGRAD_CORE_ESTIMATORS_NODE_MESSAGES_H_
