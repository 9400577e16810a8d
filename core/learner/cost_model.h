// How much CPU time a trial costs, from its options alone: the cost model of
// docs/results/cost-model.md, used to print a sweep's estimated CPU hours
// before it runs (`totalgrad sweep submit`, `totalgrad run`).
//
// A particle method's gradient step costs, per horizon step t and particle,
//   a + a_m + b N + c N^2            (policy and cost; the GP's element-wise
//                                     work; the GP's P x N x N product)
// plus, for the batch-importance-weighted methods, q_m P per particle (the
// P x P weights): step = H P (a + a_m + b N + c N^2) + H q_m P^2. A trial
// adds per learned episode e (N = H e transitions of data): the GP training
// (~ g N^3), the model-predicted cost (a forward pass of
// predicted_cost_particles particles), the real and evaluation episodes.
// PILCO: BFGS over moment matching (~ k min(N, M)^2 per episode) and the FITC
// inducing-input fits above M = gp_inducing points.
//
// The constants were measured with `totalgrad bench trial` and `bench
// iteration` on one machine (kReferenceMachine; OpenBLAS SkylakeX kernels):
// on another CPU the estimate scales by that CPU's speed. Accuracy on the
// reference machine: within ~5 % of `bench trial` for the paper protocol
// (docs/results/cost-model.md).
#ifndef TOTALGRAD_CORE_LEARNER_COST_MODEL_H_
#define TOTALGRAD_CORE_LEARNER_COST_MODEL_H_

#include "core/learner/trial.h"

namespace totalgrad::learner {

inline constexpr char kReferenceMachine[] =
    "AMD EPYC (Zen 5), one core, OpenBLAS 0.3.21 SkylakeX kernels";

struct TrialCostEstimate {
  double policy_cpu = 0;      // gradient steps (or PILCO's optimisation)
  double model_cpu = 0;       // GP hyperparameters (+ FITC inducing inputs)
  double other_cpu = 0;       // predicted cost, real and evaluation episodes
  double total_cpu() const { return policy_cpu + model_cpu + other_cpu; }
};

// Estimated CPU seconds of RunTrial(options) with one thread on the reference
// machine. `options` must be valid (TrialOptions::Validate); the estimate of
// an invalid one is meaningless but finite.
TrialCostEstimate EstimateTrialCost(const TrialOptions& options);

}  // namespace totalgrad::learner

#endif  // TOTALGRAD_CORE_LEARNER_COST_MODEL_H_
