#include "core/learner/cost_model.h"

#include <algorithm>
#include <cmath>
#include <string>

namespace totalgrad::learner {
namespace {

// Seconds per particle and horizon step of a gradient step (RP, fitted to
// `bench trial --method RP` at P = 300, H = 30, N = 30..450; docs/results/
// cost-model.md): a + b N + c N^2.
constexpr double kStepConstant = 3.42e-7;
constexpr double kStepPerData = 6.31e-9;
constexpr double kStepPerDataSquared = 7.96e-11;

// Per method: extra seconds per particle-step (a_m) and per particle pair and
// horizon step (q_m, the batch importance weights), from the methods' offsets
// over RP at P = 300 (bench trial) split by TP's scan over P = 100, 300, 1000
// (bench iteration at N = 120): one third linear in P, two thirds in P^2.
struct MethodCost {
  estimators::Method method;
  double per_particle;  // a_m
  double per_pair;      // q_m
};
using estimators::Method;
constexpr MethodCost kMethodCosts[] = {
    {Method::kRp, 0.0, 0.0},          {Method::kGr, 5.6e-8, 0.0},
    {Method::kLr, 2.30e-7, 1.53e-9},  {Method::kTp, 4.04e-7, 2.69e-9},
    {Method::kGlr, 2.52e-7, 1.68e-9}, {Method::kGtp, 3.89e-7, 2.59e-9},
    {Method::kGtpSn, 4.07e-7, 2.72e-9}, {Method::kDel, 0.0, 0.0},
};

// GP hyperparameter training per episode: g N^3 (default iteration budget).
constexpr double kGpTrainingPerDataCubed = 9.4e-9;
// The model-predicted cost's rollout relative to a gradient step of as many
// particles (forward pass only).
constexpr double kForwardFraction = 0.9;
// Seconds per simulated real-plant step (real and evaluation episodes).
constexpr double kPlantStep = 1.1e-5;

// PILCO (tip cost, angle_features auto, default BFGS budget): per episode
// kPilcoBase + kPilcoPerSupportSquared min(N, M)^2 for the optimisation, and
// for N > M a FITC inducing-input fit of kPilcoFitPerUnit N M^2 seconds per
// unit of its iteration budget (the first fit 1500 iterations, later ones
// 500, as PILCO).
constexpr double kPilcoBase = 0.8;
constexpr double kPilcoPerSupportSquared = 2.8e-4;
constexpr double kPilcoFitFirst = 72.0 / (330.0 * 300.0 * 300.0);
constexpr double kPilcoFitLater = 30.0 / (420.0 * 300.0 * 300.0);

double StepSeconds(const MethodCost& m, double n, double particles, int horizon) {
  return horizon * particles *
             (kStepConstant + m.per_particle + kStepPerData * n + kStepPerDataSquared * n * n) +
         horizon * m.per_pair * particles * particles;
}

const MethodCost& CostOf(estimators::Method method) {
  for (const MethodCost& m : kMethodCosts)
    if (method == m.method) return m;
  return kMethodCosts[0];
}

}  // namespace

TrialCostEstimate EstimateTrialCost(const TrialOptions& options) {
  TrialCostEstimate estimate;
  const int horizon = std::max(options.scene.horizon, 1);
  const double plant_episode = kPlantStep * horizon;
  estimate.other_cpu += plant_episode;  // the random episode
  const bool pilco = options.method == estimators::Method::kPilco;
  const int inducing = InducingInputs(options);
  bool fitted_before = false;
  for (int e = 1; e <= options.episodes; ++e) {
    const double n = static_cast<double>(horizon) * e;
    estimate.model_cpu += kGpTrainingPerDataCubed * n * n * n;
    if (pilco) {
      const double support = inducing > 0 ? std::min(n, static_cast<double>(inducing)) : n;
      estimate.policy_cpu += kPilcoBase + kPilcoPerSupportSquared * support * support;
      if (inducing > 0 && n > inducing) {
        const double unit = n * inducing * inducing;
        estimate.model_cpu += (fitted_before ? kPilcoFitLater : kPilcoFitFirst) * unit;
        fitted_before = true;
      }
    } else {
      const double support = inducing > 0 ? std::min(n, static_cast<double>(inducing)) : n;
      const MethodCost& m = CostOf(options.method);
      estimate.policy_cpu +=
          options.policy_steps * StepSeconds(m, support, options.particles, horizon);
      estimate.other_cpu += kForwardFraction *
                            StepSeconds(kMethodCosts[0], support, options.predicted_cost_particles,
                                        horizon);
    }
    estimate.other_cpu += plant_episode * (1 + options.eval_rollouts);
  }
  return estimate;
}

}  // namespace totalgrad::learner
