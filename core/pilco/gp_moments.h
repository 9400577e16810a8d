// Gaussian-process prediction at a Gaussian input by exact moment matching
// (PILCO's gp0 / gp1 / gp2, pilco-spec.md 4.3), with reverse-mode derivatives.
//
// For D independent SE-ARD output GPs over E inputs with "support points" X
// (N x E: the training inputs of a full GP, or the inducing inputs of FITC)
// and weights beta_a (N), the posterior mean is m_a(x) = sum_i beta_ai
// k_a(x_i, x). For x ~ N(m, s) this computes
//
//   mean_a   = E[m_a(x)],
//   cov_ab   = Cov(m_a(x), m_b(x))                           (all a, b)
//              + delta_ab (sf_a^2 - tr(Vw_a Q_aa))           (model_variance)
//              + delta_ab sn_a^2                             (include_noise)
//              + delta_ab jitter,
//   cross    = s^-1 Cov(x, f)  (E x D, computed without inverting s, so it is
//              defined for singular s as well: it is (s + Lambda_a)^-1 sum_i
//              beta_ai q_ai (x_i - m) for column a),
//
// with Vw_a the "variance weights": K_a^-1 (gp0) or Kmm^-1 - B_a^-1 (FITC,
// gp1). model_variance = false is gp2, the policy's mean-function-only
// predictor, which PILCO uses with jitter = 1e-6.
//
// Everything is evaluated in log space (no overflow for inputs far from the
// data: the results then go to 0, finitely). The N x N matrices Q_ab are not
// kept: the backward pass recomputes them, so memory stays O(N^2) per call.
//
// Thread safety: free functions; GaussianInputGp is a plain value.
#ifndef TOTALGRAD_CORE_PILCO_GP_MOMENTS_H_
#define TOTALGRAD_CORE_PILCO_GP_MOMENTS_H_

#include <vector>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "core/common/types.h"
#include "core/gp/fitc.h"
#include "core/gp/gp.h"

namespace totalgrad::pilco {

// What moment matching needs of a (full or sparse) GP with D outputs.
struct GaussianInputGp {
  RowMatrix inputs;              // N x E support points
  RowMatrix inv_lengthscale_sq;  // D x E, 1 / l_{a,m}^2
  Vector signal_var;             // D, sf_a^2
  Vector noise_var;              // D, sn_a^2
  Matrix beta;                   // N x D
  // D matrices N x N, symmetric (K_a^-1, or Kmm^-1 - B_a^-1 for FITC). May be
  // empty, and must be non-empty for model_variance = true.
  std::vector<Matrix> variance_weights;

  int num_points() const { return static_cast<int>(inputs.rows()); }
  int num_inputs() const { return static_cast<int>(inputs.cols()); }
  int num_outputs() const { return static_cast<int>(beta.cols()); }
};

// Builds a full GP from data: inputs N x E, targets N x D, log_hyp D x (E + 2)
// with row a = [log l_{a,1..E}, log sf_a, log sn_a] (PILCO's layout). K_a =
// k_a(X, X) + sn_a^2 I is factorised by Cholesky without any added jitter (as
// PILCO's solve_chol). Errors: InvalidArgument for shapes, N == 0 or
// non-finite numbers; FailedPrecondition naming the output whose K_a is not
// positive definite.
absl::StatusOr<GaussianInputGp> GaussianInputGpFromData(const RowMatrix& inputs,
                                                        const RowMatrix& targets,
                                                        const RowMatrix& log_hyp);

// Copies what is needed from a trained full GpModel (its cached K^-1 and beta,
// including any jitter GpModel added).
GaussianInputGp GaussianInputGpFromModel(const gp::GpModel& model);

// The sparse (FITC) model as PILCO's gp1: support points = inducing inputs,
// beta from FITC, variance weights Kmm^-1 - B^-1.
GaussianInputGp GaussianInputGpFromFitc(const gp::FitcModel& model);

struct GaussianPredictionOptions {
  bool model_variance = true;  // gp0/gp1: add sf^2 - tr(Vw Q); false: gp2
  bool include_noise = false;  // add sn_a^2 to cov_aa (PILCO: false)
  double jitter = 0.0;         // added to every cov_aa (gp2 in PILCO: 1e-6)
};

struct GaussianPrediction {
  Vector mean;   // D
  Matrix cov;    // D x D, symmetric
  Matrix cross;  // E x D, s^-1 Cov(x, f)
};

// x ~ N(m, s): m (E), s (E x E, symmetric positive semi-definite). Errors:
// InvalidArgument for non-finite m or s; FailedPrecondition when s + Lambda_a
// or s (Lambda_a^-1 + Lambda_b^-1) + I cannot be factorised (s is not
// positive semi-definite), naming the output(s).
absl::Status PredictGaussian(const GaussianInputGp& gp, const Vector& m, const Matrix& s,
                             const GaussianPredictionOptions& options, GaussianPrediction* out);

// Reverse mode of PredictGaussian at the same (m, s): given the adjoints of
// mean (D), cov (D x D; treated as the adjoint of a symmetric output, i.e.
// symmetrised) and cross (E x D), OVERWRITES
//   *m_bar (E), *s_bar (E x E, symmetric: the gradient with respect to a
//   symmetric s), and, if non-null, *inputs_bar (N x E, adjoint of the
//   support points) and *beta_bar (N x D).
// The GP's length-scales, signal variances and variance weights are treated
// as constants. Same errors as PredictGaussian.
absl::Status PredictGaussianBackward(const GaussianInputGp& gp, const Vector& m, const Matrix& s,
                                     const GaussianPredictionOptions& options,
                                     const Vector& mean_bar, const Matrix& cov_bar,
                                     const Matrix& cross_bar, Vector* m_bar, Matrix* s_bar,
                                     RowMatrix* inputs_bar, Matrix* beta_bar);

// The length-scale part that PredictGaussianBackward leaves out: with the
// same adjoints, OVERWRITES *il_bar (D x E) with the gradient of
// <mean_bar, mean> + <cov_bar, cov> + <cross_bar, cross> with respect to
// gp.inv_lengthscale_sq (P_a = Lambda_a^-1, one row per output; the outputs'
// own length-scales may differ). Closed forms (derived for this function):
//   d log q_ai / dP_a,m = -1/2 [lambda_m (A S)_mm + lambda_m^2 (A nu_i)_m^2],
//     A = (S + Lambda_a)^-1, nu_i = x_i - m;
//   d log Q_ab,ij / dP_a,m = -1/2 [(nu_i,m - (T z_ij)_m)^2 + T_mm],
//   d log Q_ab,ij / dP_b,m = -1/2 [(nu_j,m - (T z_ij)_m)^2 + T_mm],
//     T = R^-1 S, z_ij = P_a nu_i + P_b nu_j;
//   and cross_a = A u moves with A (dA = lambda_m^2 A e_m e_m^T A dP_a,m).
// Signal and noise variances and variance weights stay constants. Cost
// O(D^2 N^2 E). Same errors as PredictGaussian.
absl::Status PredictGaussianLengthscaleAdjoint(const GaussianInputGp& gp, const Vector& m,
                                               const Matrix& s,
                                               const GaussianPredictionOptions& options,
                                               const Vector& mean_bar, const Matrix& cov_bar,
                                               const Matrix& cross_bar, RowMatrix* il_bar);

}  // namespace totalgrad::pilco

#endif  // TOTALGRAD_CORE_PILCO_GP_MOMENTS_H_
