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
  // Errors: InvalidArgument (shapes, non-finite numbers, M == 0),
  // FailedPrecondition naming the output whose Kmm or B could not be
  // factorised.
  static absl::StatusOr<FitcModel> Create(const RowMatrix& inputs, const RowMatrix& targets,
                                          const GpHyperparameters& hyperparameters,
                                          const RowMatrix& inducing);

  int num_inputs() const { return static_cast<int>(inducing_.cols()); }
  int num_outputs() const { return static_cast<int>(beta_.cols()); }
  int num_inducing() const { return static_cast<int>(inducing_.rows()); }
  const GpHyperparameters& hyperparameters() const { return hyp_; }
  const RowMatrix& inducing() const { return inducing_; }            // M x E
  const Vector beta(int a) const { return beta_.col(a); }            // M
  const Matrix& variance_weights(int a) const { return vw_[a]; }     // M x M, Kmm^-1 - B^-1

  // Same contract as GpModel::Predict (mean, variance floored at 1e-12,
  // optional Jacobians dmean_dz(p, a*E + m)), with the FITC predictive.
  void Predict(const ConstRowMatrixRef& z, const PredictOptions& options, RowMatrix* mean,
               RowMatrix* variance, RowMatrix* dmean_dz, RowMatrix* dvar_dz) const;

 private:
  FitcModel() = default;
  GpHyperparameters hyp_;
  RowMatrix inducing_;
  Matrix beta_;             // M x D
  std::vector<Matrix> vw_;  // D x (M x M)
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

// PILCO's start: M distinct training inputs chosen uniformly at random
// (M <= N).
RowMatrix RandomSubsetOfInputs(const RowMatrix& inputs, int m, Rng* rng);

}  // namespace totalgrad::gp

#endif  // TOTALGRAD_CORE_GP_FITC_H_
