// Gaussian shaping (GS; paper section 5.2 and Algorithm 1; pipps-spec.md 5.5):
// the cost node of step t is replaced by the expected cost under the Gaussian
// fitted to the particles x_t, E_t = E_{N(mean_t, cov_t)}[c]. The estimators
// need its derivatives e_mean = dE_t/dmean_t and e_cov = dE_t/dcov_t
// (symmetric convention), and from them
//  * the shaped value of each particle, the scalar that replaces c(x_t^i) in
//    the LR part (GLR, GTP):
//      g_i = e_mean^T d_i + d_i^T e_cov d_i - (P-1)/P tr(e_cov cov)
//    (Algorithm 1's e_mu m_i + e_Sigma (v_i - 2 w_i) with e_cov symmetric),
//    which sums to zero over the particles;
//  * the pathwise (RP) cotangent that replaces (1/P) dc/dx(x_t^i) (GTP):
//      dE_t/dx_t^i = e_mean / P + 2/(P-1) e_cov d_i   (GaussianFitBackward).
//
// Two ways to get e_mean and e_cov:
//  * sampled (the paper's "by sampling from this Gaussian, and using the RP
//    gradient"): K fresh draws x_k = mean + L zeta_k,
//      e_mean = (1/K) sum_k dc/dx(x_k),
//      e_cov  = CholeskyBackward(L, tril((1/K) sum_k dc/dx(x_k) zeta_k^T)),
//    unbiased for the exact derivatives; works for any cost with a gradient;
//  * exact: closed forms under a Gaussian (gaussian::GaussianCost, pilco-spec.md
//    3.3-3.4). Exact for the angle cost; for the tip cost it is PILCO's
//    loss_cp, i.e. the expectation under the moment-matched Gaussian of
//    [x; sin x_a; cos x_a], an approximation of the true Gaussian expectation.
// Both use the fit's covariance with its jitter (1e-6 I by default, as the
// authors' demo), which keeps the factor defined for P <= S.
//
// Thread safety: functions are re-entrant.
#ifndef TOTALGRAD_CORE_ESTIMATORS_GAUSSIAN_SHAPING_H_
#define TOTALGRAD_CORE_ESTIMATORS_GAUSSIAN_SHAPING_H_

#include "absl/status/statusor.h"
#include "core/common/rng.h"
#include "core/common/types.h"
#include "core/estimators/gaussian_fit.h"
#include "core/gaussian/expected_cost.h"
#include "core/tasks/cost.h"

namespace totalgrad::estimators {

// The jitter Gaussian shaping and DEL add to the fitted covariance.
inline constexpr double kShapingJitter = 1e-6;

struct ExpectedCostGradient {
  double value = 0;  // E[c] (for the sampled kind: the sample mean of c)
  Vector dmean;      // S
  Matrix dcov;       // S x S, symmetric
};

// Sampled derivatives with `samples` draws from *rng (samples x S normals,
// row by row). `cost` must accept S-column states.
void SampledExpectedCostGradient(const tasks::StateCost& cost, const GaussianFit& fit,
                                 int samples, Rng* rng, ExpectedCostGradient* out);

// Exact derivatives at N(fit.mean, fit.covariance + jitter I) from the
// cost's closed form (tasks::StateCost::GaussianExpectation). Errors as
// gaussian::GaussianCost::Evaluate (non-finite fit).
absl::Status ExactExpectedCostGradient(const gaussian::GaussianCost& cost, const GaussianFit& fit,
                                       ExpectedCostGradient* out);

// Shaped values g (P, overwritten). Sums to zero up to round-off.
void ShapedValues(const GaussianFit& fit, const ExpectedCostGradient& e, Vector* g);

}  // namespace totalgrad::estimators

#endif  // TOTALGRAD_CORE_ESTIMATORS_GAUSSIAN_SHAPING_H_
