#include "core/study/frozen_problem.h"

#include <utility>

#include "absl/strings/str_cat.h"
#include "core/common/rng.h"
#include "core/gp/training.h"
#include "core/gaussian/angle_features.h"

namespace totalgrad::study {
namespace {

std::string AnglesText(const std::vector<int>& angles) {
  if (angles.empty()) return "raw state";
  std::string text = "sin/cos of state";
  for (int a : angles) absl::StrAppend(&text, " ", a);
  return text;
}

}  // namespace

absl::StatusOr<std::unique_ptr<FrozenProblem>> FrozenProblemFromSnapshot(
    const learner::TrialSnapshot& snapshot, SnapshotPolicy which) {
  absl::StatusOr<learner::TrialOptions> parsed = learner::TrialOptionsFromStoredPairs(snapshot.options);
  if (!parsed.ok()) return absl::InvalidArgumentError(absl::StrCat("snapshot options: ", parsed.status().message()));
  const learner::TrialOptions& options = *parsed;
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
  out->owned_scene = std::make_unique<tasks::Scene>(*std::move(scene));
  const tasks::Scene& sc = *out->owned_scene;
  out->scene = sc.name;
  // The trial's features: the raw state, or the scene's angles as (sin, cos)
  // (what the trial's learner used; learner::FeatureAngles decides for both).
  out->angle_indices = learner::FeatureAngles(options, sc);
  if (options.policy != policy::PolicyClass::kRbf) {
    return absl::InvalidArgumentError(
        "snapshot: the trial's policy is linear; gradient studies take the RBF policy so far");
  }
  out->owned_policy = std::make_unique<learner::TrialPolicy>(
      policy::PolicyClass::kRbf, options.basis_functions,
      gaussian::FeatureDim(d, out->angle_indices), sc.max_control);
  const Vector& theta = which == SnapshotPolicy::kBefore ? snapshot.policy_parameters_before
                                                         : snapshot.policy_parameters;
  if (theta.size() != out->owned_policy->num_parameters()) {
    return absl::InvalidArgumentError(absl::StrCat(
        "snapshot: policy_parameters", which == SnapshotPolicy::kBefore ? "_before" : "",
        " has ", theta.size(), " entries; ", options.basis_functions, " basis functions on the ",
        AnglesText(out->angle_indices), " (", out->owned_policy->input_dim(), " inputs) need ",
        out->owned_policy->num_parameters()));
  }
  out->owned_policy->set_parameters(theta);
  out->policy = &out->owned_policy->rbf();

  // The trial's model of the episode: its training set and problem, built as
  // the trial builds them (its features, full GP, no thread pool).
  const learner::Transitions data{snapshot.states, snapshot.forces, snapshot.next_states};
  absl::StatusOr<learner::ModelProblem> model = learner::ModelProblem::Build(
      learner::MakeGpTrainingSet(data, out->angle_indices), snapshot.hyperparameters,
      learner::SparseModelFit{}, out->angle_indices, out->owned_policy.get(), sc,
      options.model_noise_multiplier, /*pool=*/nullptr, learner::GpOptions(options));
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
  if (!out->angle_indices.empty()) {
    absl::StrAppend(&out->source, ", features ", AnglesText(out->angle_indices));
  }
  return out;
}

absl::StatusOr<SceneSyntheticProblem> MakeSceneSyntheticProblem(const tasks::Scene& scene,
                                                                const SceneSyntheticOptions& options,
                                                                ThreadPool* pool) {
  if (options.data < 2) return absl::InvalidArgumentError("synthetic problem: data must be >= 2");
  if (options.basis_functions < 1) {
    return absl::InvalidArgumentError("synthetic problem: basis_functions must be >= 1");
  }
  const int d = scene.state_dim(), f_count = scene.control_dim();
  Rng rng(options.seed, Stream::kStudy, 1);
  learner::Transitions transitions;
  transitions.states.resize(options.data, d);
  transitions.next_states.resize(options.data, d);
  transitions.forces.resize(options.data * f_count);  // N F, transition-major
  const Vector lo = scene.mu0.cwiseMin(scene.target).array() - 1.0;
  const Vector hi = scene.mu0.cwiseMax(scene.target).array() + 1.0;
  for (int n = 0; n < options.data; ++n) {
    Vector x(d);
    for (int m = 0; m < d; ++m) x(m) = rng.Uniform(lo(m), hi(m));
    // Each control uniform in its bounds, drawn in control order (one
    // control: the one draw it always was).
    Vector u(f_count);
    for (int j = 0; j < f_count; ++j) u(j) = rng.Uniform(-scene.max_control(j), scene.max_control(j));
    Vector next;
    if (absl::Status st = scene.plant->Step(x, u, &next); !st.ok()) return st;
    for (int m = 0; m < d; ++m) next(m) += scene.observation_noise_std(m) * rng.Normal();
    transitions.states.row(n) = x.transpose();
    transitions.next_states.row(n) = next.transpose();
    transitions.forces.segment(n * f_count, f_count) = u;
  }
  // The features a particle method's trial would use on this scene.
  const bool cartpole = scene.is_cartpole();
  SceneSyntheticProblem out;
  out.angle_indices =
      learner::UsesSinCosFeatures(estimators::Method::kRp, options.angle_features, cartpole)
          ? scene.angle_indices
          : std::vector<int>();
  const std::vector<int>& angles = out.angle_indices;
  const learner::GpTrainingSet set = learner::MakeGpTrainingSet(transitions, angles);
  gp::GpHyperparameters hyp = gp::InitialHyperparameters(set.inputs, set.targets);
  if (options.train_iterations > 0) {
    gp::TrainingOptions training;
    training.max_iterations = options.train_iterations;
    absl::StatusOr<gp::TrainingSummary> summary =
        gp::TrainHyperparameters(set.inputs, set.targets, training, &hyp);
    if (!summary.ok()) return summary.status();
  }
  // Centres drawn in the raw state, then mapped to the features (as the
  // particle learner initialises a sin/cos policy); unit length-scales.
  const int c = options.basis_functions;
  out.policy = std::make_unique<learner::TrialPolicy>(
      policy::PolicyClass::kRbf, c, gaussian::FeatureDim(d, angles), scene.max_control);
  Rng policy_rng(options.seed, Stream::kPolicyInit);
  policy::RbfPolicy raw(c, d, scene.max_control);
  raw.Initialize(scene.mu0, Vector::Constant(d, 1.0), 1.0, &policy_rng);
  RowMatrix centres;
  gaussian::StatesToFeatures(raw.centres(), angles, &centres);
  const int f = out.policy->input_dim();
  Vector params(out.policy->num_parameters());
  Eigen::Map<RowMatrix>(params.data(), c, f) = centres;
  params.segment(c * f, f).setZero();
  params.tail(raw.weights().size()) = raw.weights();  // C x F
  out.policy->set_parameters(params);
  absl::StatusOr<learner::ModelProblem> model =
      learner::ModelProblem::Build(set, hyp, learner::SparseModelFit{}, angles, out.policy.get(),
                                   scene, options.noise_variance_multiplier, pool,
                                   gp::GpModelOptions{options.variance_rank_tolerance});
  if (!model.ok()) return model.status();
  out.model = std::make_unique<learner::ModelProblem>(*std::move(model));
  return out;
}

absl::StatusOr<std::unique_ptr<FrozenProblem>> FrozenProblemFromScene(
    const tasks::Scene& scene, const SceneSyntheticOptions& options) {
  // The study's cells take one control so far (the synthetic problem itself
  // takes any: `bench iteration --scene` uses it on the double pendulum).
  auto out = std::make_unique<FrozenProblem>();
  out->owned_scene = std::make_unique<tasks::Scene>(scene);
  out->owned_scene->horizon = options.horizon;
  absl::StatusOr<SceneSyntheticProblem> built =
      MakeSceneSyntheticProblem(*out->owned_scene, options, /*pool=*/nullptr);
  if (!built.ok()) return built.status();
  out->owned_policy = std::move(built->policy);
  out->model_problem = std::move(built->model);
  out->angle_indices = std::move(built->angle_indices);
  out->policy = &out->owned_policy->rbf();
  out->model = out->model_problem->full_model();
  out->problem = out->model_problem->problem();
  out->problem.horizon = options.horizon;
  out->scene = scene.name;
  out->source = absl::StrCat("synthetic problem on scene ", scene.name, ", seed ", options.seed,
                             ", N = ", options.data, " random transitions, features ",
                             AnglesText(out->angle_indices),
                             options.train_iterations > 0 ? ", trained GP" : ", untrained GP");
  return out;
}

absl::StatusOr<std::unique_ptr<FrozenProblem>> FrozenProblemFromSynthetic(
    const estimators::SyntheticProblemOptions& options, learner::AngleFeatures angle_features) {
  const tasks::SceneDefinition* definition = tasks::FindSceneDefinition(options.scene);
  const bool cartpole = definition == nullptr || definition->plant == tasks::PlantKind::kCartPole;
  if (cartpole && !learner::UsesSinCosFeatures(estimators::Method::kRp, angle_features, true)) {
    // The paper's synthetic cart-pole problem on the raw state, as before
    // (existing study files give the same bits).
    absl::StatusOr<std::unique_ptr<estimators::SyntheticProblem>> synthetic =
        estimators::MakeSyntheticProblem(options);
    if (!synthetic.ok()) return synthetic.status();
    auto out = std::make_unique<FrozenProblem>();
    // The synthetic problem owns its pieces (heap objects): the pointers stay valid.
    out->synthetic = *std::move(synthetic);
    out->problem = out->synthetic->problem;
    out->model = out->synthetic->model.get();
    out->policy = out->synthetic->policy.get();
    out->scene = options.scene;
    out->source = absl::StrCat("synthetic problem, seed ", options.seed, ", N = ", options.data,
                               " random transitions, cost ", options.cost,
                               options.train_iterations > 0 ? ", trained GP" : ", untrained GP");
    return out;
  }
  absl::StatusOr<tasks::Scene> scene =
      tasks::MakeScene(options.scene, options.cost, options.horizon);
  if (!scene.ok()) return scene.status();
  const SceneSyntheticOptions scene_synthetic{options, angle_features};
  absl::StatusOr<std::unique_ptr<FrozenProblem>> out = FrozenProblemFromScene(*scene, scene_synthetic);
  if (out.ok()) absl::StrAppend(&(*out)->source, ", cost ", options.cost);
  return out;
}

}  // namespace totalgrad::study
