#include "core/study/frozen_problem.h"

#include <utility>

#include "absl/strings/str_cat.h"

namespace totalgrad::study {

absl::StatusOr<std::unique_ptr<FrozenProblem>> FrozenProblemFromSnapshot(
    const learner::TrialSnapshot& snapshot, SnapshotPolicy which) {
  learner::TrialOptions options;
  for (const auto& [key, value] : snapshot.options) {
    if (absl::Status st = learner::SetTrialOption(key, value, &options); !st.ok()) {
      return absl::InvalidArgumentError(absl::StrCat("snapshot options: ", st.message()));
    }
  }
  const bool sincos = options.angle_features == "sincos" ||
                      (options.angle_features == "auto" && options.method == "PILCO");
  if (sincos) {
    return absl::InvalidArgumentError(
        "snapshot: the trial's model uses (sin, cos) angle features; gradient studies need the "
        "raw-state model (run the trial with --angle-features raw)");
  }
  const Eigen::Index n = snapshot.states.rows();
  if (n < 1 || snapshot.states.cols() != tasks::kCartPoleStateDim ||
      snapshot.next_states.rows() != n || snapshot.next_states.cols() != tasks::kCartPoleStateDim ||
      snapshot.forces.size() != n) {
    return absl::InvalidArgumentError(absl::StrCat(
        "snapshot: data shapes disagree (states ", snapshot.states.rows(), " x ",
        snapshot.states.cols(), ", forces ", snapshot.forces.size(), ", next_states ",
        snapshot.next_states.rows(), " x ", snapshot.next_states.cols(), ")"));
  }
  if (options.gp_inducing > 0 && n > options.gp_inducing) {
    return absl::InvalidArgumentError(absl::StrCat(
        "snapshot: the trial's model of episode ", snapshot.episode, " is a sparse GP (FITC, ",
        options.gp_inducing, " inducing inputs for N = ", n,
        " transitions), which snapshots do not keep; gradient studies rebuild the full GP only "
        "(run the trial with --gp-inducing 0)"));
  }
  absl::StatusOr<tasks::Scene> scene = tasks::MakeScene(options.scene);
  if (!scene.ok()) {
    return absl::InvalidArgumentError(absl::StrCat("snapshot scene: ", scene.status().message()));
  }

  auto out = std::make_unique<FrozenProblem>();
  out->scene = std::make_unique<tasks::Scene>(*std::move(scene));
  // The trial's model inputs [observed state, force] and targets (observed
  // state differences), computed as TrialData does.
  const int s_dim = tasks::kCartPoleStateDim;
  RowMatrix inputs(n, s_dim + 1), targets(n, s_dim);
  inputs.leftCols(s_dim) = snapshot.states;
  inputs.col(s_dim) = snapshot.forces;
  for (Eigen::Index r = 0; r < n; ++r) {
    targets.row(r) = snapshot.next_states.row(r) - snapshot.states.row(r);
  }
  absl::StatusOr<gp::GpModel> model =
      gp::GpModel::Create(inputs, targets, snapshot.hyperparameters);
  if (!model.ok()) {
    return absl::Status(model.status().code(),
                        absl::StrCat("snapshot GP model: ", model.status().message()));
  }
  out->model = std::make_unique<gp::GpModel>(*std::move(model));

  out->policy = std::make_unique<policy::RbfPolicy>(options.basis_functions, s_dim,
                                                    out->scene->plant.params().max_force);
  const Vector& theta = which == SnapshotPolicy::kBefore ? snapshot.policy_parameters_before
                                                         : snapshot.policy_parameters;
  if (theta.size() != out->policy->num_parameters()) {
    return absl::InvalidArgumentError(absl::StrCat(
        "snapshot: policy_parameters", which == SnapshotPolicy::kBefore ? "_before" : "",
        " has ", theta.size(), " entries; ", options.basis_functions,
        " basis functions on the raw state need ", out->policy->num_parameters()));
  }
  out->policy->set_parameters(theta);

  estimators::Problem& p = out->problem;
  p.model = out->model.get();
  p.policy = out->policy.get();
  p.cost = out->scene->cost.get();
  p.mu0 = out->scene->mu0;
  p.initial_std = out->scene->initial_std;
  p.horizon = out->scene->horizon;
  p.noise_variance_multiplier = options.model_noise_multiplier;
  out->source = absl::StrCat("trial snapshot, method ", options.method, ", seed ", options.seed,
                             ", episode ", snapshot.episode, " (policy ",
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
  // Move the owned pieces; the problem's pointers stay valid (heap objects).
  out->model = std::move((*synthetic)->model);
  out->policy = std::move((*synthetic)->policy);
  out->scene = std::move((*synthetic)->scene);
  out->problem = (*synthetic)->problem;
  out->source = absl::StrCat("synthetic problem, seed ", options.seed, ", N = ", options.data,
                             " random transitions, cost ", options.cost,
                             options.train_iterations > 0 ? ", trained GP" : ", untrained GP");
  return out;
}

}  // namespace totalgrad::study
