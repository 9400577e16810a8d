// Jump (likelihood-ratio) cotangents of one transition node: estimates of
// dG/dzeta_i computed from the sampled costs still to come, G (paper sections
// 2.2 and 5.1; pipps-spec.md 5.3 and 5.7).
//
// With scalar weights A (the 1/P of the objective's particle mean included),
// every LR flavour gives a cotangent on zeta_i = (mu_i, v_i) of the form
//   mean_bar_i = sum_j w_ij Delta_ij / v_i
//   var_bar_i  = sum_j w_ij (Delta_ij^2 / v_i^2 - 1/v_i) / 2
// with Delta_ij = x_{t+1}^j - mu_i (the score of log N(x^j; mu_i, v_i)):
//  * plain LR:  w_ij = [i == j] (G_i - b_i) / P
//  * BIW-LR:    w_ij = c_ij (G_j - b_i) / P, the batch importance weights
//    c_ij = p_i(x^j) / sum_k p_k(x^j) of sample j under the mixture of every
//    particle's predictive (each column of c sums to 1), and the BIW baseline
//    b_i = sum_{j != i} c_ij G_j / sum_{j != i} c_ij (the paper's section 2.2).
// Densities and weights are formed in log space (log-sum-exp per sample), so
// far-apart particles give weights that underflow to 0, never 0/0.
//
// DEL's cotangent is of another kind: LR at a Gaussian fitted to the
// particles, whose derivative reaches the particles x_{t+1}^i themselves
// (DensityEstimationCotangent); the caller sends it through RpZetaCotangent.
//
// All functions read next_state as the samples x_{t+1}: they are not meant
// for resampled (GR) steps. Thread safety: re-entrant.
#ifndef TOTALGRAD_CORE_ESTIMATORS_LIKELIHOOD_RATIO_H_
#define TOTALGRAD_CORE_ESTIMATORS_LIKELIHOOD_RATIO_H_

#include "core/common/types.h"
#include "core/estimators/gaussian_fit.h"
#include "core/estimators/node_messages.h"
#include "core/estimators/rollout.h"

namespace totalgrad::estimators {

// b_i = (sum_j G_j - G_i) / (P - 1); 0 for P = 1 (no other particle).
Vector LeaveOneOutBaseline(const Vector& cost_to_go);

// log_density(i, j) = log N(x_{t+1}^j; mu_i, diag v_i) (P x P; row i is the
// source particle, column j the sample).
void TransitionLogDensities(const StepRecord& step, RowMatrix* log_density);

// log c_ij = log_density(i, j) - logsumexp_k log_density(k, j) (P x P).
// exp(log c) has columns summing to 1. A column whose densities are all -Inf
// (non-finite particles) is left -Inf; callers see non-finite results. When
// `weights` is non-null it receives c itself (P x P), taken from the
// log-sum-exp's own exponentials (no second P x P exp).
void BiwLogWeights(const StepRecord& step, RowMatrix* log_weights, RowMatrix* weights = nullptr);

// The effective sample size of BIW weights c (P x P, BiwLogWeights: row i
// the source particle, column j the sample), averaged over the sources:
//   ESS = (1/P) sum_i (sum_j c_ij)^2 / sum_j c_ij^2,
// Kish's effective number of the samples that source i's likelihood-ratio
// term weighs, in [1, P] for a row with mass: P for uniform weights, 1 when
// each source weighs only its own sample (the degeneracy of low model
// noise). A row whose weights all underflow to 0 counts 0; a NaN weight
// gives NaN.
double MeanEffectiveSampleSize(const RowMatrix& weights);

// The BIW baseline from log weights (P x P) and costs to go (P): b_i =
// sum_{j != i} c_ij G_j / sum_{j != i} c_ij, evaluated with row i's largest
// log weight over j != i factored out so that it is exact even when every
// c_ij underflows. Where no j != i has a finite log weight (P = 1 included)
// the leave-one-out mean is used.
void BiwBaseline(const RowMatrix& log_weights, const Vector& cost_to_go, Vector* baseline);
// The same, reading the linear weights c for rows whose off-diagonal mass is
// comfortably representable (> 1e-250) and the log weights for the others.
void BiwBaseline(const RowMatrix& log_weights, const RowMatrix& weights, const Vector& cost_to_go,
                 Vector* baseline);

// The per-pair variant (pipps-spec.md 5.3 [REC]): b_ij = sum_{k != j} c_ik G_k
// / sum_{k != j} c_ik, which leaves out the sample j the term is evaluated at
// (P x P, overwritten). Computed without cancellation: for all j but row i's
// heaviest sample by subtracting one term from the row sums (the remaining
// sum is at least the heaviest weight), for the heaviest one directly. Where
// no k != j has a finite log weight the leave-one-out mean G_{-j} is used.
void BiwPairBaseline(const RowMatrix& log_weights, const Vector& cost_to_go, RowMatrix* baseline);

// Plain LR: w_ij = [i == j] scale (G_i - b_i).
void PlainLrCotangent(const StepRecord& step, const Vector& cost_to_go, const Vector& baseline,
                      double scale, ZetaCotangent* out);

// Weighted LR: w_ij = scale weights(i, j) (G_j - b_i), weights in linear
// space (P x P, source x sample). weights = I gives PlainLrCotangent.
void WeightedLrCotangent(const StepRecord& step, const RowMatrix& weights,
                         const Vector& cost_to_go, const Vector& baseline, double scale,
                         ZetaCotangent* out);
// The same with a per-pair baseline b_ij (P x P): w_ij = scale c_ij (G_j - b_ij).
void WeightedLrCotangent(const StepRecord& step, const RowMatrix& weights,
                         const Vector& cost_to_go, const RowMatrix& pair_baseline, double scale,
                         ZetaCotangent* out);

// DEL: for q = N(fit.mean, fit.covariance + jitter) and weights A_i (P, with
// the baseline and 1/P included), the cotangent on the particles (P x S,
// overwritten) of the surrogate sum_i A_i log q(x_i) with the x_i held fixed
// in the score and the fit differentiated:
//   mean_bar = sum_i A_i Sigma^-1 d_i
//   cov_bar  = 1/2 sum_i A_i (Sigma^-1 d_i d_i^T Sigma^-1 - Sigma^-1)
//   x_bar_i  = GaussianFitBackward(mean_bar, cov_bar)
void DensityEstimationCotangent(const GaussianFit& fit, const Vector& weights, RowMatrix* x_bar);

}  // namespace totalgrad::estimators

#endif  // TOTALGRAD_CORE_ESTIMATORS_LIKELIHOOD_RATIO_H_
