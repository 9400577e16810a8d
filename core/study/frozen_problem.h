// A frozen gradient problem for studies (study.h): a GP dynamics model, an
// RBF policy at fixed parameters, the start distribution and the cost, owned
// together with the estimators::Problem that points into them.
//
// Two sources:
//  * a trial snapshot (learner::TrialSnapshot, saved at a chosen episode by
//    `totalgrad trial --snapshot-episodes`): the problem is built from the
//    snapshot's data and hyperparameters by the trial's own builder
//    (learner::ModelProblem), so the model is the trial's model of that
//    episode;
//  * a synthetic problem (estimators::MakeSyntheticProblem).
//
// Studies rebuild the raw-state model (GP inputs [x, u]); a snapshot whose
// model was built on (sin, cos) angle features (PILCO's default, or any
// method's with angle_features = sincos) is refused, and so is one whose model was a sparse GP (gp_inducing > 0 and
// N > gp_inducing: snapshots do not keep the inducing inputs). PILCO's moment
// matching runs on the same model and policy with angle_index -1 (study.h).
//
// Thread safety: a FrozenProblem is immutable once built; share it read-only.
#ifndef TOTALGRAD_CORE_STUDY_FROZEN_PROBLEM_H_
#define TOTALGRAD_CORE_STUDY_FROZEN_PROBLEM_H_

#include <memory>
#include <string>

#include "absl/status/statusor.h"
#include "core/estimators/rollout.h"
#include "core/estimators/synthetic_problem.h"
#include "core/gp/gp.h"
#include "core/learner/problem_builder.h"
#include "core/learner/trial.h"
#include "core/policy/rbf_policy.h"
#include "core/tasks/scene.h"

namespace totalgrad::study {

struct FrozenProblem {
  // The problem the estimators differentiate; its horizon is the scene's, a
  // study overrides it per cell.
  estimators::Problem problem;
  const gp::GpModel* model = nullptr;         // the full GP its dynamics predict with (raw state)
  const policy::RbfPolicy* policy = nullptr;  // the policy at the studied parameters
  // Human-readable provenance, e.g. "trial snapshot, episode 3 (policy
  // before optimisation), N = 90".
  std::string source;

  // Owners of what the members above point into (those of the source used).
  std::unique_ptr<tasks::Scene> scene;
  std::unique_ptr<policy::RbfPolicy> owned_policy;
  std::unique_ptr<learner::ModelProblem> model_problem;
  std::unique_ptr<estimators::SyntheticProblem> synthetic;

  FrozenProblem() = default;
  FrozenProblem(const FrozenProblem&) = delete;
  FrozenProblem& operator=(const FrozenProblem&) = delete;
};

// Which policy of a snapshot the gradient is taken at: the one entering the
// episode's optimisation (its gradient is what the optimiser used first) or
// the optimised one.
enum class SnapshotPolicy { kBefore, kAfter };

// Errors: InvalidArgument naming the problem (an unknown option key in the
// snapshot, sin/cos angle features, a sparse-GP episode, data or parameter
// shapes that do not match the options); the GP's FailedPrecondition if K
// cannot be factorised.
absl::StatusOr<std::unique_ptr<FrozenProblem>> FrozenProblemFromSnapshot(
    const learner::TrialSnapshot& snapshot, SnapshotPolicy which);

// Errors: those of estimators::MakeSyntheticProblem.
absl::StatusOr<std::unique_ptr<FrozenProblem>> FrozenProblemFromSynthetic(
    const estimators::SyntheticProblemOptions& options);

}  // namespace totalgrad::study

#endif  // TOTALGRAD_CORE_STUDY_FROZEN_PROBLEM_H_
