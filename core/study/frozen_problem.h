// A frozen gradient problem for studies (study.h): a GP dynamics model, an
// RBF policy at fixed parameters, the start distribution and the cost of one
// scene, owned together with the estimators::Problem that points into them.
//
// Three sources:
//  * a trial snapshot (learner::TrialSnapshot, saved at a chosen episode by
//    `totalgrad trial --snapshot-episodes`) on any one-control scene: the
//    problem is built from the snapshot's data and hyperparameters by the
//    trial's own builder (learner::ModelProblem) on the trial's features
//    (learner::FeatureAngles: the raw state, or the scene's angles as (sin,
//    cos)), so the model is the trial's model of that episode, bit for bit;
//  * a synthetic problem on a scene of the catalog (SceneSyntheticOptions):
//    a GP on random transitions of the scene's plant, on the scene's index
//    sets, and a random RBF policy;
//  * the paper's synthetic cart-pole problem (estimators::MakeSyntheticProblem,
//    raw state), kept as it was so that existing study files give the same
//    bits.
//
// Refused by name: a snapshot whose model was a sparse GP (gp_inducing > 0
// and N > gp_inducing: snapshots do not keep the inducing inputs), and a
// synthetic problem on a scene of more than one control (RunStudy also
// refuses a snapshot of one: the study's cells are one-control so far).
// PILCO's moment matching runs on the same model and policy
// with the problem's angle_indices (study.h).
//
// Thread safety: a FrozenProblem is immutable once built; share it read-only.
#ifndef TOTALGRAD_CORE_STUDY_FROZEN_PROBLEM_H_
#define TOTALGRAD_CORE_STUDY_FROZEN_PROBLEM_H_

#include <memory>
#include <string>
#include <vector>

#include "absl/status/statusor.h"
#include "core/common/thread_pool.h"
#include "core/estimators/rollout.h"
#include "core/estimators/synthetic_problem.h"
#include "core/gp/gp.h"
#include "core/learner/problem_builder.h"
#include "core/learner/trial.h"
#include "core/learner/trial_options.h"
#include "core/policy/rbf_policy.h"
#include "core/tasks/scene.h"

namespace totalgrad::study {

struct FrozenProblem {
  // The problem the estimators differentiate; its horizon is the scene's, a
  // study overrides it per cell.
  estimators::Problem problem;
  // The full GP its dynamics predict with, on the features of angle_indices
  // (inputs [phi(x), u]).
  const gp::GpModel* model = nullptr;
  // The policy at the studied parameters, on the same features.
  const policy::RbfPolicy* policy = nullptr;
  // The state angles the model and the policy see as (sin, cos), strictly
  // increasing; empty: the raw state.
  std::vector<int> angle_indices;
  std::string scene;  // the scene's name
  // Human-readable provenance, e.g. "trial snapshot, episode 3 (policy
  // before optimisation), N = 90".
  std::string source;

  // Owners of what the members above point into (those of the source used).
  std::unique_ptr<tasks::Scene> owned_scene;
  std::unique_ptr<learner::TrialPolicy> owned_policy;  // an RBF policy
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
// snapshot, a sparse-GP episode, a scene of several controls, data or
// parameter shapes that do not match the options); the GP's
// FailedPrecondition if K cannot be factorised.
absl::StatusOr<std::unique_ptr<FrozenProblem>> FrozenProblemFromSnapshot(
    const learner::TrialSnapshot& snapshot, SnapshotPolicy which);

// A synthetic problem on a scene: N transitions of the scene's plant from
// states drawn uniformly per dimension over [min(mu0, target) - 1,
// max(mu0, target) + 1], controls uniform within the bounds, the scene's
// observation noise on the next state; the GP on the features the angle
// choice gives for a particle method (learner::FeatureAngles; `auto` is the
// scene's index sets except on the cart-pole) with PILCO's initial
// hyperparameters (trained for train_iterations L-BFGS iterations if > 0);
// an RBF policy of basis_functions centres ~ N(mu0, I) mapped to features,
// unit length-scales, random weights. Draws: data from (seed,
// Stream::kStudy, 1), the policy from (seed, Stream::kPolicyInit).
// The synthetic problem's options (data >= 2 transitions, horizon, basis
// functions, seed, train_iterations, noise_variance_multiplier,
// variance_rank_tolerance) are a study file's; their `scene` and `cost` are
// not read here (the scene argument is the problem's).
struct SceneSyntheticOptions : estimators::SyntheticProblemOptions {
  learner::AngleFeatures angle_features = learner::AngleFeatures::kAuto;
};

// What MakeSceneSyntheticProblem builds: the policy and the model problem
// over it (the problem points into both and into the scene).
struct SceneSyntheticProblem {
  std::unique_ptr<learner::TrialPolicy> policy;  // an RBF policy
  std::unique_ptr<learner::ModelProblem> model;
  std::vector<int> angle_indices;
};

// `scene` must outlive the result; `pool` (may be null) goes to the model's
// adapters. Errors: InvalidArgument (data < 2, basis_functions < 1, a scene
// of several controls), the plant's step errors, the GP's.
absl::StatusOr<SceneSyntheticProblem> MakeSceneSyntheticProblem(const tasks::Scene& scene,
                                                                const SceneSyntheticOptions& options,
                                                                ThreadPool* pool);

// The synthetic problem of a study file: the paper's raw-state synthetic
// cart-pole problem (estimators::MakeSyntheticProblem, unchanged) when the
// scene is a cart-pole scene and the features resolve to the raw state;
// otherwise MakeSceneSyntheticProblem on options.scene with options.cost.
// Errors: those of the builder used; InvalidArgument for an unknown scene.
absl::StatusOr<std::unique_ptr<FrozenProblem>> FrozenProblemFromSynthetic(
    const estimators::SyntheticProblemOptions& options,
    learner::AngleFeatures angle_features = learner::AngleFeatures::kAuto);

// The same on a scene the caller built (e.g. one the catalog does not have);
// the scene is copied into the result.
absl::StatusOr<std::unique_ptr<FrozenProblem>> FrozenProblemFromScene(
    const tasks::Scene& scene, const SceneSyntheticOptions& options);

}  // namespace totalgrad::study

#endif  // TOTALGRAD_CORE_STUDY_FROZEN_PROBLEM_H_
