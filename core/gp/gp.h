// Gaussian-process dynamics model: one independent GP per output dimension,
// squared-exponential ARD kernel, Gaussian likelihood.
//
//   k_a(z, z') = sf_a^2 exp(-1/2 sum_m (z_m - z'_m)^2 / l_{a,m}^2)
//   y_a = f_a(z) + noise, noise ~ N(0, sn_a^2)
//
// For the cart-pole the inputs are z = [observed state (4), force (N)] (E = 5)
// and the targets are observed state differences (D = 4).
//
// GpModel caches everything that does not change while a policy is optimised
// (K^-1 with K = K_a(X, X) + sn_a^2 I, beta_a = K^-1 y_a, the length-scale-
// scaled inputs), so that predicting P particles costs one P x N by N x N
// matrix product per output (BLAS-3) plus O(P N E) element-wise work; with
// GpModelOptions::variance_rank_tolerance > 0, two thin P x N x r products
// instead where the model's spectrum allows r < N/2 (see GpModelOptions).
//
// Thread safety: a constructed GpModel is immutable; Predict is thread-safe.
// Predict can spread its outputs over a ThreadPool; the outputs are computed
// independently, so the numbers are the same bits for any pool size.
#ifndef TOTALGRAD_CORE_GP_GP_H_
#define TOTALGRAD_CORE_GP_GP_H_

#include <vector>

#include "absl/status/statusor.h"
#include "core/common/thread_pool.h"
#include "core/common/types.h"

namespace totalgrad::gp {

// Predictive variances below this are round-off; GpModel::Predict and
// FitcModel::Predict floor their variances here.
inline constexpr double kVarianceFloor = 1e-12;

// Hyperparameters of all outputs, in log space.
struct GpHyperparameters {
  RowMatrix log_lengthscales;  // D x E: row a holds log l_{a,m}
  Vector log_signal_std;       // D: log sf_a
  Vector log_noise_std;        // D: log sn_a

  int num_outputs() const { return static_cast<int>(log_lengthscales.rows()); }
  int num_inputs() const { return static_cast<int>(log_lengthscales.cols()); }
  // Packs output a as [log l_{a,1..E}, log sf_a, log sn_a] (E + 2 entries).
  Vector Packed(int a) const;
  void SetPacked(int a, const Vector& packed);
  // OK, or InvalidArgument naming the first non-finite entry.
  absl::Status ValidateFinite() const;
};

// What building or training a GP on (inputs, targets) with `hyp` requires:
// N >= 1 rows of E >= 1 inputs, targets N x D (D >= 1), hyperparameters of
// D x E lengthscales and D signal and noise scales, every number finite.
// OK, or InvalidArgument naming the first violation.
absl::Status ValidateGpData(const RowMatrix& inputs, const RowMatrix& targets,
                            const GpHyperparameters& hyp);

// Options fixed when a model is built.
struct GpModelOptions {
  // 0 (default): the predictive variance uses the exact K^-1, bit for bit the
  // path that existed before the option. t > 0 (finite, < 1): per output a,
  // the "low rank plus diagonal" form of K^-1 in the variance and its
  // Jacobian (never in the mean, which keeps beta = K^-1 y from the Cholesky
  // factor):
  //
  //   Kf = K_a(X, X) (noise-free) = U diag(lambda) U^T, lambda descending,
  //   s = sn_a^2 + jitter_a, so K = Kf + s I and exactly
  //   K^-1 = U diag(1/(lambda_i + s) - 1/s) U^T + I/s.
  //   B_r  = U_r diag(-lambda_i / (s (lambda_i + s)))_{i<=r} U_r^T + I/s
  //
  // keeps the top r eigenpairs. Bound (a priori, for every query z): with
  // c_i = u_i^T k(X, z), the joint Gram matrix of [X; z] is PSD, so
  // sum_i c_i^2 / lambda_i <= sf^2 (c_i = 0 where lambda_i = 0), and
  //   0 <= k^T B_r k - k^T K^-1 k = sum_{i>r} (c_i^2 / lambda_i) lambda_i^2 / (s (lambda_i + s))
  //                              <= sf^2 lambda_{r+1}^2 / (s (lambda_{r+1} + s)),
  // i.e. the variance is lowered by at most bound(r) * s with
  //   bound(r) = sf^2 lambda_{r+1}^2 / (s^2 (lambda_{r+1} + s))   (lambda_{N+1} = 0).
  // rank(a) is the smallest r with bound(r) <= t, which makes the variance's
  // relative error <= t whenever the variance includes the noise
  // (noise_variance_multiplier >= 1, no jitter; in general <= t s / (mult sn^2)).
  // (bench/precision_levers.py's sum_{i>r} sf^2 lambda_i^2 / s^3 is a looser
  // form of the same bound: it gives ranks ~10 % larger.) The product
  // A = Kstar B_r = ((Kstar U_r M_r) U_r^T) + Kstar / s costs 4 P N r flops
  // against 2 P N^2, so it is used only when 2 r < N; otherwise that output
  // takes the exact path (rank(a) = N), bit for bit as with t = 0. The
  // variance Jacobian is the exact derivative of the approximate variance.
  // The eigendecomposition (Eigen's SelfAdjointEigenSolver on the N x N
  // matrix, once per output at Create) is not done when t = 0.
  double variance_rank_tolerance = 0;
};

struct PredictOptions {
  // The predictive variance is sf^2 - k^T K^-1 k + noise_variance_multiplier *
  // sn^2 (the paper's sigma_f^2 + sigma_n^2). 25 gives GTP+sigma_n's model;
  // 0 gives the latent (noise-free) variance. Training is not affected.
  double noise_variance_multiplier = 1.0;
};

class GpModel {
 public:
  // Builds the model from N training pairs: inputs N x E, targets N x D,
  // hyperparameters D x E. Factorises K_a by Cholesky; if that fails, adds
  // jitter 1e-8 * sf_a^2, then x10 up to 1e-2 * sf_a^2, and records the jitter
  // used. "Fails" includes a factorisation that succeeds only by round-off: a
  // pivot L_ii^2 <= N * eps * max diag(K) (duplicated inputs with tiny noise).
  // Errors: InvalidArgument for mismatched shapes, N == 0 or non-finite
  // numbers (the message names which), or options.variance_rank_tolerance
  // not finite, negative or >= 1 (the message names it); FailedPrecondition
  // when even the largest jitter does not make K_a positive definite, or
  // (t > 0 only) when the eigendecomposition of Kf does not converge.
  static absl::StatusOr<GpModel> Create(const RowMatrix& inputs, const RowMatrix& targets,
                                        const GpHyperparameters& hyperparameters,
                                        const GpModelOptions& options = GpModelOptions());

  int num_inputs() const { return num_inputs_; }
  int num_outputs() const { return num_outputs_; }
  int num_data() const { return num_data_; }
  const GpHyperparameters& hyperparameters() const { return hyp_; }
  // Jitter added to the diagonal of K_a (0 when none was needed).
  double jitter(int a) const { return outputs_[a].jitter; }
  const GpModelOptions& options() const { return options_; }
  // The rank r of output a's variance (GpModelOptions): r < N/2 when the
  // low-rank form is used, N (num_data) when the exact K^-1 is.
  int rank(int a) const { return outputs_[a].rank; }
  // The r the bound asks for, whether or not it is used (N when the
  // tolerance is 0): rank(a) == bound_rank(a) exactly when 2 r < N.
  int bound_rank(int a) const { return outputs_[a].bound_rank; }
  // Cached quantities, for moment-matching predictors (PILCO) that reuse them.
  const RowMatrix& inputs() const { return inputs_; }    // N x E
  const RowMatrix& targets() const { return targets_; }  // N x D
  // k_inverse is always the exact K^-1, whatever the options (PILCO reads it).
  const Matrix& k_inverse(int a) const { return outputs_[a].k_inverse; }  // N x N
  const Vector& beta(int a) const { return outputs_[a].beta; }            // N

  // Batched prediction for P query rows z (P x E).
  //   mean (P x D):      mean(p, a) = k_a(z_p)^T beta_a
  //   variance (P x D):  variance(p, a) = sf_a^2 - k^T K_a^-1 k + mult * sn_a^2,
  //                      floored at 1e-12 (the floor only ever catches round-off;
  //                      where it binds the variance's Jacobian row is zero).
  //   dmean_dz, dvar_dz (P x D*E, optional, may be null):
  //                      dmean_dz(p, a*E + m) = d mean(p, a) / d z_{p,m}.
  // Output matrices are resized by the call. Jacobians are computed only when
  // asked for, so an evaluation rollout pays nothing for them. `mean` must not
  // be null; `variance` may be null when dvar_dz is null too, which skips the
  // P x N x N product (a mean-only prediction costs O(P N E)). Requesting
  // Jacobians never changes the mean and variance values. `pool` (may be
  // null: the calling thread does everything) runs one task per output,
  // most expensive first (by rank(a)), so that outputs of unequal rank
  // spread over the threads as evenly as whole outputs can;
  // results do not depend on its size.
  void Predict(const ConstRowMatrixRef& z, const PredictOptions& options, RowMatrix* mean,
               RowMatrix* variance, RowMatrix* dmean_dz, RowMatrix* dvar_dz,
               ThreadPool* pool = nullptr) const;

 private:
  struct Output {
    RowMatrix scaled_inputs;  // N x E, X / l_a
    Vector scaled_sq_norms;   // N, |X_n / l_a|^2
    Matrix k_inverse;         // N x N, (K_a + sn_a^2 I + jitter I)^-1, symmetric
    // Low rank plus diagonal (GpModelOptions), used when rank < N:
    int rank = 0;             // r, or N for the exact path
    int bound_rank = 0;       // r the bound asks for
    Matrix lowrank_w;         // N x r, U_r diag(-lambda_i / (s (lambda_i + s)))
    Matrix lowrank_ut;        // r x N, U_r^T
    double inv_noise = 0;     // 1 / s, s = sn_a^2 + jitter
    Vector beta;              // N, K^-1 y_a
    Matrix mean_rhs;          // N x (1 + E), [beta, beta .* Xs]
    Matrix var_rhs;           // N x (1 + E), [1, Xs]
    Vector inv_lengthscales;  // E, 1 / l_a
    double signal_var = 0;    // sf_a^2
    double noise_var = 0;     // sn_a^2
    double jitter = 0;
  };
  GpModel() = default;
  // Output a's columns of Predict's results (already sized by Predict).
  void PredictOutput(int a, const ConstRowMatrixRef& z, const PredictOptions& options,
                     RowMatrix* mean, RowMatrix* variance, RowMatrix* dmean_dz,
                     RowMatrix* dvar_dz) const;

  int num_inputs_ = 0;
  int num_outputs_ = 0;
  int num_data_ = 0;
  GpHyperparameters hyp_;
  GpModelOptions options_;
  RowMatrix inputs_;
  RowMatrix targets_;
  std::vector<Output> outputs_;
  // Output indices by descending rank (ties: ascending index): the order in
  // which Predict hands outputs to a pool. Which thread computes an output
  // does not change its numbers, so the order only affects wall time.
  std::vector<int> outputs_by_cost_;
};

}  // namespace totalgrad::gp

#endif  // TOTALGRAD_CORE_GP_GP_H_
