// One backward pass for every particle method (paper sections 3-5,
// Algorithm 1; pipps-spec.md 5 and 9): the estimators differ only in which
// pieces it is assembled from.
//
// Walking t = H-1 .. 0 over the nodes x_t -> x_{t+1} of a recorded rollout,
// the pass keeps per particle the message gamma_i = dJ/dx_{t+1}^i and the cost
// to go G_i, and at every node:
//  1. cost node at x_{t+1}: plain (local value c_i, pathwise cotangent
//     dc/dx / P) or Gaussian-shaped (local value g_i, pathwise cotangent
//     dE_t/dx_i; see gaussian_shaping.h). G += local value.
//  2. pathwise branch (RP): dG/dzeta from gamma + the cost node's cotangent,
//     after the resampler's backward map when the rollout was resampled (GR).
//  3. jump branch: dG/dzeta from G directly: LR (plain or BIW weights, with
//     a baseline) or DEL (LR at the Gaussian fitted to x_{t+1}).
//  4. combination: the node's estimate is k_LR * jump + (1 - k_LR) * pathwise
//     in zeta space (Algorithm 1's "combine LR and RP in state space"), with
//     k_LR = 0 (pathwise only), 1 (jump only) or, for total propagation, the
//     inverse-variance rule CombinationWeight() of the traces of the sample
//     variances over particles of the two branches' per-particle parameter
//     gradients at this node. A branch with weight exactly 0 is not evaluated
//     into the result, so an exploding (Inf) branch never turns into 0 * Inf.
//  5. the combined cotangent crosses the node (TransitionVjp and the policy's
//     adjoint): its force part gives each particle's parameter contribution
//     at this node, its state part is the message to x_t. A pure jump method
//     sends no message (each node's jump is already a total derivative).
//
// Thread safety: re-entrant.
#ifndef TOTALGRAD_CORE_ESTIMATORS_TOTAL_PROPAGATION_H_
#define TOTALGRAD_CORE_ESTIMATORS_TOTAL_PROPAGATION_H_

#include <string>
#include <vector>

#include "absl/status/statusor.h"
#include "core/common/rng.h"
#include "core/estimators/estimator.h"
#include "core/estimators/gaussian_resampling.h"
#include "core/estimators/node_messages.h"
#include "core/estimators/rollout.h"

namespace totalgrad::estimators {

enum class CostNodeKind { kPlain, kGaussianShaped };
enum class JumpKind { kNone, kLikelihoodRatio, kDensityEstimation };

struct BackwardConfig {
  CostNodeKind cost = CostNodeKind::kPlain;
  GsDerivative gs_derivative = GsDerivative::kSampled;  // kGaussianShaped only
  bool pathwise = true;                 // evaluate the RP branch
  JumpKind jump = JumpKind::kNone;      // the jump branch, if any
  LrWeights lr_weights = LrWeights::kBatchImportance;   // kLikelihoodRatio only
  LrBaseline lr_baseline = LrBaseline::kBatchImportance;  // LR and DEL (DEL: biw = loo)
  // Pathwise and jump together: a value in [0, 1] fixes k_LR; otherwise the rule.
  double forced_k_lr = -1.0;
  // The resampler the rollout was recorded with (GR), or null. Only with a
  // pathwise-only configuration.
  const StepResampler* resampler = nullptr;
};

struct BackwardResult {
  Vector gradient;          // n
  RowMatrix per_particle;   // P x n, particle i's contributions (the 1/P inside); rows sum to gradient
  // When both branches are evaluated, per node t (H entries): the weight on
  // the jump branch and the two branches' trace variances.
  std::vector<double> k_lr;
  std::vector<TraceVariance> var_pathwise, var_jump;
  // When the jump branch uses BIW weights, per node t (H entries): their
  // effective sample size (MeanEffectiveSampleSize). Read only: recording it
  // changes no number of the pass.
  std::vector<double> ess;
};

// Runs the pass over `rollout` (recorded for `problem` with Jacobians, and
// with config.resampler iff that is set). Sampled shaping derivatives draw P
// x S normals per node from *rng (nodes in reverse order). Errors:
// InvalidArgument for a configuration with no branch, a resampler with a jump
// branch, a rollout without Jacobians or of another problem, or exact shaping
// of a cost without a closed form. Non-finite values (particles, fits,
// derivatives) are not errors: they reach the result.
absl::Status BackwardPass(const Problem& problem, const Rollout& rollout,
                          const BackwardConfig& config, Rng* rng, BackwardResult* result);

// A named method as a forward recording and a backward configuration.
struct MethodRecipe {
  BackwardConfig backward;
  bool resample = false;                 // Gaussian resampling in the forward pass (GR)
  double noise_variance_factor = 1.0;    // multiplies problem.noise_variance_multiplier
};

// The recipe of GR, LR, TP, GLR, GTP, GTP+sn or DEL (RP too, although
// MakeEstimator gives RP its dedicated RpEstimator). InvalidArgument for
// PILCO or invalid options (EstimatorOptions::Validate()).
absl::StatusOr<MethodRecipe> RecipeFor(Method method, const EstimatorOptions& options);

// An Estimator assembled from a recipe: forward pass, BackwardPass, and the
// per-particle gradients g^(i) = P * contribution_i with their variance.
class ParticleEstimator final : public Estimator {
 public:
  ParticleEstimator(Method method, MethodRecipe recipe);
  std::string Name() const override { return MethodName(method_); }
  Method method() const { return method_; }
  absl::Status Estimate(const Problem& problem, const EstimateOptions& options, Rng* rng,
                        GradientEstimate* estimate) override;
  const MethodRecipe& recipe() const { return recipe_; }
  // The per-node diagnostics of the last Estimate (k_lr and variances).
  const BackwardResult& last_backward() const { return backward_; }

 private:
  Method method_;
  MethodRecipe recipe_;
  GaussianResampler resampler_;  // used when recipe_.resample
  Rollout rollout_;          // reused between calls to avoid reallocations
  BackwardResult backward_;
};

}  // namespace totalgrad::estimators

#endif  // TOTALGRAD_CORE_ESTIMATORS_TOTAL_PROPAGATION_H_
