// A frozen, self-contained estimation problem for tests, benchmarks and
// gradient studies: a GP fitted to N one-step transitions of the real
// cart-pole from random states and forces, a randomly initialised RBF policy,
// the swing-up start distribution and a cost.
//
// The GP uses PILCO's initial hyperparameters (no training) unless
// train_iterations > 0, so building one is fast and deterministic.
#ifndef TOTALGRAD_CORE_ESTIMATORS_SYNTHETIC_PROBLEM_H_
#define TOTALGRAD_CORE_ESTIMATORS_SYNTHETIC_PROBLEM_H_

#include <memory>
#include <string>

#include "absl/status/statusor.h"
#include "core/estimators/rollout.h"
#include "core/tasks/scene.h"

namespace totalgrad::estimators {

struct SyntheticProblemOptions {
  int data = 450;           // N transitions
  int horizon = 30;
  int basis_functions = 50;
  std::string cost = "angle";
  std::string scene = "cartpole-swingup";
  uint64_t seed = 1;
  int train_iterations = 0;  // GP hyperparameter L-BFGS iterations (0 = initial values)
  double noise_variance_multiplier = 1.0;
  // gp::GpModelOptions::variance_rank_tolerance of the model (0 = exact).
  double variance_rank_tolerance = 0;
};

// Owns the model, policy and scene and the adapters `problem` points into
// (problem.dynamics = *dynamics over *model, problem.policy = *controller
// over *policy, both without a thread pool). Not copyable (the problem holds
// pointers into it).
struct SyntheticProblem {
  std::unique_ptr<gp::GpModel> model;
  std::unique_ptr<policy::RbfPolicy> policy;
  std::unique_ptr<tasks::Scene> scene;
  std::unique_ptr<GpDynamics> dynamics;
  std::unique_ptr<RbfParticlePolicy> controller;
  Problem problem;

  SyntheticProblem() = default;
  SyntheticProblem(const SyntheticProblem&) = delete;
  SyntheticProblem& operator=(const SyntheticProblem&) = delete;
};

absl::StatusOr<std::unique_ptr<SyntheticProblem>> MakeSyntheticProblem(
    const SyntheticProblemOptions& options);

}  // namespace totalgrad::estimators

#endif  // TOTALGRAD_CORE_ESTIMATORS_SYNTHETIC_PROBLEM_H_
