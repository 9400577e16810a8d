#include "core/study/frozen_problem.h"

#include <utility>

#include "absl/strings/str_cat.h"

namespace totalgrad::study {

absl::StatusOr<std::unique_ptr<FrozenProblem>> FrozenProblemFromSnapshot(
    const learner::TrialSnapshot& snapshot, SnapshotPolicy which) {
  absl::StatusOr<learner::TrialOptions> parsed = learner::TrialOptionsFromPairs(snapshot.options);
  if (!parsed.ok()) return absl::InvalidArgumentError(absl::StrCat("snapshot options: ", parsed.status().message()));
  const learner::TrialOptions& options = *parsed;
  if (learner::UsesSinCosFeatures(options)) {
    return absl::InvalidArgumentError(
        "snapshot: the trial's model uses (sin, cos) angle features; gradient studies need the "
        "raw-state model (run the trial with --angle-features raw)");
  }
  absl::StatusOr<tasks::Scene> scene = tasks::MakeScene(options.scene);
  if (!scene.ok()) {
    return absl::InvalidArgumentError(absl::StrCat("snapshot scene: ", scene.status().message()));
  }
  const Eigen::Index n = snapshot.states.rows();
  const int d = scene->state_dim();
  // forces: N F, transition-major (F controls per transition).
  if (n < 1 || snapshot.states.cols() != d || snapshot.next_states.rows() != n ||
      snapshot.next_states.cols() != d || snapshot.forces.size() != n * scene->control_dim()) {
    return absl::InvalidArgumentError(absl::StrCat(
        "snapshot: data shapes disagree (states ", snapshot.states.rows(), " x ",
        snapshot.states.cols(), ", forces ", snapshot.forces.size(), ", next_states ",
        snapshot.next_states.rows(), " x ", snapshot.next_states.cols(), ")"));
  }
  const int inducing = learner::InducingInputs(options);
  if (inducing > 0 && n > inducing) {
    return absl::InvalidArgumentError(absl::StrCat(
        "snapshot: the trial's model of episode ", snapshot.episode, " is a sparse GP (FITC, ",
        inducing, " inducing inputs for N = ", n,
        " transitions), which snapshots do not keep; gradient studies rebuild the full GP only "
        "(run the trial with --gp-inducing 0)"));
  }
  auto out = std::make_unique<FrozenProblem>();
  out->scene = std::make_unique<tasks::Scene>(*std::move(scene));
  out->owned_policy = std::make_unique<policy::RbfPolicy>(
      options.basis_functions, d, out->scene->max_control);
  const Vector& theta = which == SnapshotPolicy::kBefore ? snapshot.policy_parameters_before
                                                         : snapshot.policy_parameters;
  if (theta.size() != out->owned_policy->num_parameters()) {
    return absl::InvalidArgumentError(absl::StrCat(
        "snapshot: policy_parameters", which == SnapshotPolicy::kBefore ? "_before" : "",
        " has ", theta.size(), " entries; ", options.basis_functions,
        " basis functions on the raw state need ", out->owned_policy->num_parameters()));
  }
  out->owned_policy->set_parameters(theta);
  out->policy = out->owned_policy.get();

  // The trial's model of the episode: its training set and problem, built as
  // the trial builds them (raw features, full GP, no thread pool).
  const learner::Transitions data{snapshot.states, snapshot.forces, snapshot.next_states};
  absl::StatusOr<learner::ModelProblem> model = learner::ModelProblem::Build(
      learner::MakeGpTrainingSet(data, /*angle_indices=*/{}), snapshot.hyperparameters,
      learner::SparseModelFit{}, /*angle_indices=*/{}, out->policy, *out->scene,
      options.model_noise_multiplier, /*pool=*/nullptr);
  if (!model.ok()) {
    return absl::Status(model.status().code(), absl::StrCat("snapshot ", model.status().message()));
  }
  out->model_problem = std::make_unique<learner::ModelProblem>(*std::move(model));
  out->model = out->model_problem->full_model();
  out->problem = out->model_problem->problem();
  out->source = absl::StrCat("trial snapshot, method ", estimators::MethodName(options.method),
                             ", seed ", options.seed, ", episode ", snapshot.episode, " (policy ",
                             which == SnapshotPolicy::kBefore ? "before" : "after",
                             " the episode's optimisation), N = ", n, " transitions, cost ",
                             options.scene.cost);
  return out;
}

absl::StatusOr<std::unique_ptr<FrozenProblem>> FrozenProblemFromSynthetic(
    const estimators::SyntheticProblemOptions& options) {
  absl::StatusOr<std::unique_ptr<estimators::SyntheticProblem>> synthetic =
      estimators::MakeSyntheticProblem(options);
  if (!synthetic.ok()) return synthetic.status();
  auto out = std::make_unique<FrozenProblem>();
  // The synthetic problem owns its pieces (heap objects): the pointers stay valid.
  out->synthetic = *std::move(synthetic);
  out->problem = out->synthetic->problem;
  out->model = out->synthetic->model.get();
  out->policy = out->synthetic->policy.get();
  out->source = absl::StrCat("synthetic problem, seed ", options.seed, ", N = ", options.data,
                             " random transitions, cost ", options.cost,
                             options.train_iterations > 0 ? ", trained GP" : ", untrained GP");
  return out;
}

}  // namespace totalgrad::study
