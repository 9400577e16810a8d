// Sparse GP by FITC (Snelson & Ghahramani) with M inducing inputs shared by
// the D outputs, as PILCO uses once the data exceed the number of inducing
// inputs (pilco-spec.md 4.3 "gp1", 4.5):
//
//   Kmm   = k_a(Z, Z) + 1e-6 I (ridge),   Kmn = k_a(Z, X),
//   Lam_a = diag(K_nn - Q_nn) + sn_a^2 I, Q_nn = Knm Kmm^-1 Kmn,
//   B_a   = Kmm + Kmn Lam_a^-1 Knm,
//   beta_a = B_a^-1 Kmn Lam_a^-1 y_a,
//   mean_a(z) = k_a(z, Z) beta_a,
//   var_a(z)  = sf_a^2 - k_a(z, Z) (Kmm^-1 - B_a^-1) k_a(Z, z) [+ mult sn_a^2].
//
// The hyperparameters are those of the full GP (PILCO trains them on the full
// data first); only the inducing inputs Z are trained, by minimising the FITC
// negative log marginal likelihood summed over the outputs, with L-BFGS
// (LBFGSpp; PILCO's minimize also switches to L-BFGS above 1000 parameters,
// and M x E = 1800 here). PILCO starts Z at a random subset of the training
// inputs and gives the first fit 1500 line searches, later warm-started fits
// 500.
//
// Thread safety: a constructed FitcModel is immutable; Predict is thread-safe.
#ifndef TOTALGRAD_CORE_GP_FITC_H_
#define TOTALGRAD_CORE_GP_FITC_H_

#include <string>
#include <vector>

#include "absl/status/statusor.h"
#include "core/common/rng.h"
#include "core/common/types.h"
#include "core/gp/gp.h"

namespace totalgrad::gp {

inline constexpr double kFitcRidge = 1e-6;

class FitcModel {
 public:
  // inputs N x E, targets N x D, hyperparameters D x E, inducing M x E.
  // Errors: InvalidArgument (shapes, non-finite numbers, M == 0, sf^2, sn^2 or
  // 1 / l overflowing), FailedPrecondition naming the output whose Kmm or B
  // could not be factorised.
  static absl::StatusOr<FitcModel> Create(const RowMatrix& inputs, const RowMatrix& targets,
                                          const GpHyperparameters& hyperparameters,
                                          const RowMatrix& inducing);

  int num_inputs() const { return static_cast<int>(inducing_.cols()); }
  int num_outputs() const { return static_cast<int>(beta_.cols()); }
  int num_inducing() const { return static_cast<int>(inducing_.rows()); }
  const GpHyperparameters& hyperparameters() const { return hyp_; }
  const RowMatrix& inducing() const { return inducing_; }            // M x E
  const Vector beta(int a) const { return beta_.col(a); }            // M
  // M x M, Kmm^-1 - B^-1, exactly symmetric.
  const Matrix& variance_weights(int a) const { return outputs_[a].variance_weights; }

  // Batched point prediction with the contract of GpModel::Predict (gp.h),
  // with the FITC predictive in place of the exact one:
  //   mean (P x D):      mean(p, a) = k_a(z_p, Z) beta_a
  //   variance (P x D):  sf_a^2 - k^T Vw_a k + mult * sn_a^2, floored at 1e-12
  //                      (where the floor binds the Jacobian row is zero)
  //   dmean_dz, dvar_dz (P x D*E, optional): dmean_dz(p, a*E + m) =
  //                      d mean(p, a) / d z_{p,m}.
  // Everything that does not depend on z is cached by Create (Z / l_a,
  // |Z / l_a|^2, beta_a .* Z / l_a, Vw_a), so P queries cost per output one
  // P x M x E product (kernel), P x M x E products for the Jacobians and one
  // P x M by M x M product for the variance (BLAS-3): the full GP's work with
  // N replaced by M. `mean` must not be null; `variance` may be null when
  // dvar_dz is null too (mean only, O(P M E)). Requesting Jacobians never
  // changes the values. Thread-safe (per-thread scratch space). `pool` (may
  // be null) runs one task per output; results do not depend on its size.
  void Predict(const ConstRowMatrixRef& z, const PredictOptions& options, RowMatrix* mean,
               RowMatrix* variance, RowMatrix* dmean_dz, RowMatrix* dvar_dz,
               ThreadPool* pool = nullptr) const;

 private:
  // Output a's columns of Predict's results (already sized by Predict).
  void PredictOutput(int a, const ConstRowMatrixRef& z, const PredictOptions& options,
                     RowMatrix* mean, RowMatrix* variance, RowMatrix* dmean_dz,
                     RowMatrix* dvar_dz) const;
  struct Output {
    RowMatrix scaled_inducing;       // M x E, Z / l_a
    Vector scaled_sq_norms;          // M, |Z_m / l_a|^2
    RowMatrix beta_scaled_inducing;  // M x E, beta_a .* Z / l_a (mean Jacobian)
    Matrix variance_weights;         // M x M, Kmm^-1 - B^-1, symmetric
    Vector inv_lengthscales;         // E, 1 / l_a
    double signal_var = 0;           // sf_a^2
    double noise_var = 0;            // sn_a^2
  };
  FitcModel() = default;
  GpHyperparameters hyp_;
  RowMatrix inducing_;
  Matrix beta_;                  // M x D
  std::vector<Output> outputs_;  // D
};

// FITC negative log marginal likelihood summed over outputs, and its gradient
// with respect to the inducing inputs (M x E, row-major flattening in
// `gradient`, may be null). Returns false if a factorisation fails or a value
// is not finite.
bool FitcNlml(const RowMatrix& inputs, const RowMatrix& targets,
              const GpHyperparameters& hyperparameters, const RowMatrix& inducing,
              double* value, RowMatrix* gradient);

struct FitcTrainingOptions {
  int max_iterations = 500;  // L-BFGS iterations (PILCO: 1500 the first time, then 500)
};

struct FitcTrainingSummary {
  double initial_nlml = 0;
  double final_nlml = 0;
  int iterations = 0;                // L-BFGS iterations (0 if a line search failed)
  int evaluations = 0;               // NLML + gradient evaluations
  bool line_search_failed = false;  // caught; the best point is kept
  std::string BriefReport() const;
};

// Trains *inducing in place (warm start). Errors: InvalidArgument for shapes,
// FailedPrecondition if the NLML cannot be evaluated at the start.
absl::StatusOr<FitcTrainingSummary> TrainInducingInputs(const RowMatrix& inputs,
                                                        const RowMatrix& targets,
                                                        const GpHyperparameters& hyperparameters,
                                                        const FitcTrainingOptions& options,
                                                        RowMatrix* inducing);

// How a FITC model is fitted to a data set, as PILCO does it (pilco-spec.md
// 4.5): inducing inputs warm-started from the previous fit when there is one,
// else a random subset of the training inputs; then trained with the
// hyperparameters fixed.
struct FitcFitOptions {
  int num_inducing = 300;           // M (PILCO: 300)
  int first_fit_iterations = 1500;  // L-BFGS iterations from a random subset
  int warm_fit_iterations = 500;    // from *inducing when it is already M x E
};

// Fits Z and builds the model. *inducing is the warm start (used when it is
// num_inducing x E, otherwise replaced by RandomSubsetOfInputs drawn from
// *rng) and receives the trained inducing inputs. `summary` may be null.
// Errors: InvalidArgument when num_inducing < 1 or > N (a data set of at
// most M points is the full GP's job), and those of TrainInducingInputs and
// FitcModel::Create.
absl::StatusOr<FitcModel> FitFitcModel(const RowMatrix& inputs, const RowMatrix& targets,
                                       const GpHyperparameters& hyperparameters,
                                       const FitcFitOptions& options, RowMatrix* inducing, Rng* rng,
                                       FitcTrainingSummary* summary);

// PILCO's start: M distinct training inputs chosen uniformly at random
// (M <= N).
RowMatrix RandomSubsetOfInputs(const RowMatrix& inputs, int m, Rng* rng);

}  // namespace totalgrad::gp

#endif  // TOTALGRAD_CORE_GP_FITC_H_
