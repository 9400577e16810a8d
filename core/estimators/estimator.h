// Particle gradient estimators of dJ/dtheta, J the expected episode cost of
// the policy under the learned model (paper sections 2-5).
//
// An estimator runs the forward pass it needs (estimators/rollout.h) and a
// backward pass that sends per-node messages (estimators/total_propagation.h).
// Every estimate comes with the per-particle gradients' sample variance, which
// the paper's optimiser uses to normalise its step.
//
// Methods (estimators/method.h, ParticleMethods()):
//   RP      reparameterisation gradient (backpropagation through time)
//   GR      RP with Gaussian resampling of the particles at every step
//   LR      BIW-LR with the BIW baseline (batch importance weighted LR)
//   TP      total propagation: per step, RP and LR combined with
//           k_LR = 1 / (1 + var_LR / var_RP)
//   GLR     LR on the Gaussian-shaped cost values
//   GTP     TP on the Gaussian-shaped cost (Algorithm 1)
//   GTP+sn  GTP with the model noise variance x25 during policy optimisation
//   DEL     density-estimation LR (LR at a Gaussian fitted to the particles)
//
// Thread safety: an Estimator may keep scratch space; use one per thread.
#ifndef TOTALGRAD_CORE_ESTIMATORS_ESTIMATOR_H_
#define TOTALGRAD_CORE_ESTIMATORS_ESTIMATOR_H_

#include <memory>
#include <string>
#include <vector>

#include "absl/status/statusor.h"
#include "core/common/option_table.h"
#include "core/common/rng.h"
#include "core/estimators/method.h"
#include "core/estimators/rollout.h"

namespace totalgrad::estimators {

struct GradientEstimate {
  double objective = 0;            // J estimated by the forward pass (plain costs)
  Vector gradient;                 // n, estimate of dJ/dtheta
  // Per-particle gradients g^(i) (their mean is `gradient`): P x n. Filled
  // only when the caller asks for them (EstimateOptions).
  RowMatrix per_particle;
  Vector per_particle_variance;    // n, sample variance of g^(i) over particles
  bool finite = true;              // false: some value was non-finite; do not use
  // Total propagation's weight on LR per step t = 0..H-1 (the node producing
  // x_{t+1}); empty for methods that do not combine.
  std::vector<double> k_lr;
  // The BIW importance weights' effective sample size per step t = 0..H-1
  // (likelihood_ratio.h, MeanEffectiveSampleSize); empty for methods
  // without them (RP, GR, DEL, plain weights).
  std::vector<double> ess;
};

struct EstimateOptions {
  int particles = 300;
  bool keep_per_particle = false;  // keep the P x n matrix in the estimate
};

class Estimator {
 public:
  virtual ~Estimator() = default;
  virtual std::string Name() const = 0;
  // One estimate for `problem` with fresh random numbers from *rng.
  // Errors: InvalidArgument for an inconsistent problem or an option the
  // problem does not support (exact shaping derivatives of an unknown cost).
  virtual absl::Status Estimate(const Problem& problem, const EstimateOptions& options, Rng* rng,
                                GradientEstimate* estimate) = 0;
};

// Which per-sample weights the LR part of LR, TP, GLR and GTP uses.
enum class LrWeights {
  kBatchImportance,  // "biw": the paper's BIW-LR (mixture of all particles' predictives)
  kPlain,            // "plain": each particle's own predictive (the authors' demo)
};
// Baseline subtracted from the cost to go in the LR part.
enum class LrBaseline {
  kBatchImportance,  // "biw": the paper's importance-weighted leave-one-out mean,
                     // b_i leaving out sample i (with plain weights: "loo")
  kBatchImportancePair,  // "biw_pair": b_ij leaving out the sample j the term is
                         // evaluated at (pipps-spec.md 5.3; with plain weights: "loo")
  kLeaveOneOut,      // "loo": (sum_j G_j - G_i) / (P - 1)
  kNone,             // "none"
};
// How Gaussian shaping gets dE[c]/dmean and dE[c]/dcov.
enum class GsDerivative {
  kSampled,  // "sampled": RP through P fresh draws from the fitted Gaussian (paper)
  kExact,    // "exact": closed form (angle and tip costs only)
};

// The canonical names of the enum values above ("biw", "plain"; "biw",
// "biw_pair", "loo", "none"; "sampled", "exact").
const EnumNames<LrWeights>& LrWeightsNames();
const EnumNames<LrBaseline>& LrBaselineNames();
const EnumNames<GsDerivative>& GsDerivativeNames();

// Options shared by the estimator family (method-specific knobs live here so
// one key=value space configures every method). Each is ignored by methods
// that do not use it.
struct EstimatorOptions {
  LrWeights lr_weights = LrWeights::kBatchImportance;      // LR, TP, GLR, GTP, GTP+sn
  LrBaseline lr_baseline = LrBaseline::kBatchImportance;   // LR, TP, GLR, GTP, GTP+sn
  GsDerivative gs_derivative = GsDerivative::kSampled;     // GLR, GTP, GTP+sn
  double sn_noise_multiplier = 25.0;  // GTP+sn: model noise variance factor (>= 0)
  // TP/GTP: a value in [0, 1] fixes k_LR at every step instead of the
  // variance rule (k = 0 reproduces the pathwise estimate, k = 1 the jump
  // one); anything else (the default, -1) uses the rule.
  double forced_k_lr = -1.0;

  // Option keys (the trial's and the study file's estimator options):
  // lr_weights, lr_baseline, gs_derivative, sn_noise_multiplier, forced_k_lr.
  static const OptionTable<EstimatorOptions>& Table();
  // InvalidArgument naming the key: sn_noise_multiplier not finite or < 0,
  // an enum value outside its names.
  absl::Status Validate() const;
  bool operator==(const EstimatorOptions&) const = default;
};

// Text forms of the enums (their *Names() tables). Parse* return
// InvalidArgument naming the valid values.
std::string LrWeightsName(LrWeights w);
std::string LrBaselineName(LrBaseline b);
std::string GsDerivativeName(GsDerivative d);
absl::Status ParseLrWeights(const std::string& text, LrWeights* out);
absl::Status ParseLrBaseline(const std::string& text, LrBaseline* out);
absl::Status ParseGsDerivative(const std::string& text, GsDerivative* out);

// The estimator of a particle method. InvalidArgument for PILCO (not a
// particle method: core/pilco), a value outside the enum, or invalid
// options (options.Validate()).
absl::StatusOr<std::unique_ptr<Estimator>> MakeEstimator(Method method,
                                                         const EstimatorOptions& options);

// Sample variance over rows of a P x n matrix (0 when P == 1).
Vector ColumnSampleVariance(const RowMatrix& per_particle);

}  // namespace totalgrad::estimators

#endif  // TOTALGRAD_CORE_ESTIMATORS_ESTIMATOR_H_
