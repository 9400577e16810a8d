#include "core/learner/problem_builder.h"

#include <utility>

#include "absl/strings/str_cat.h"
#include "core/common/check.h"
#include "core/gaussian/angle_features.h"

namespace totalgrad::learner {

void Transitions::Append(const tasks::Episode& episode) {
  const Eigen::Index h = episode.observations.rows() - 1;
  const Eigen::Index n = states.rows();
  const Eigen::Index s = episode.observations.cols();
  if (n == 0) {
    states.resize(0, s);
    next_states.resize(0, s);
    forces.resize(0);
  }
  TG_CHECK_EQ(states.cols(), s);
  const Eigen::Index old_forces = forces.size();
  states.conservativeResize(n + h, s);
  next_states.conservativeResize(n + h, s);
  forces.conservativeResize(old_forces + episode.forces.size());
  states.bottomRows(h) = episode.observations.topRows(h);
  next_states.bottomRows(h) = episode.observations.bottomRows(h);
  forces.tail(episode.forces.size()) = episode.forces;
}

GpTrainingSet MakeGpTrainingSet(const Transitions& data, const std::vector<int>& angle_indices,
                                const std::vector<int>& dynamics_inputs) {
  const int f = data.control_dim();
  TG_CHECK(data.next_states.rows() == data.size() && data.forces.size() == data.size() * f);
  TG_CHECK(dynamics_inputs.empty() || angle_indices.empty());
  RowMatrix features;
  if (dynamics_inputs.empty()) {
    gaussian::StatesToFeatures(data.states, angle_indices, &features);
  } else {
    features.resize(data.size(), static_cast<Eigen::Index>(dynamics_inputs.size()));
    for (size_t k = 0; k < dynamics_inputs.size(); ++k)
      features.col(static_cast<Eigen::Index>(k)) = data.states.col(dynamics_inputs[k]);
  }
  GpTrainingSet set;
  set.inputs.resize(data.size(), features.cols() + f);
  set.inputs.leftCols(features.cols()) = features;
  if (f == 1) {
    set.inputs.col(features.cols()) = data.forces;
  } else {
    set.inputs.rightCols(f) = Eigen::Map<const RowMatrix>(data.forces.data(), data.size(), f);
  }
  set.targets = data.next_states - data.states;
  return set;
}

absl::StatusOr<ModelProblem> ModelProblem::Build(const GpTrainingSet& data,
                                                 const gp::GpHyperparameters& hyperparameters,
                                                 const SparseModelFit& sparse,
                                                 const std::vector<int>& angle_indices,
                                                 const TrialPolicy* policy,
                                                 const tasks::Scene& scene,
                                                 double noise_variance_multiplier,
                                                 ThreadPool* pool,
                                                 const gp::GpModelOptions& gp_options) {
  TG_CHECK(policy != nullptr);
  ModelProblem out;
  if (sparse.num_inducing > 0 && data.inputs.rows() > sparse.num_inducing) {
    TG_CHECK(sparse.inducing != nullptr && sparse.rng != nullptr);
    gp::FitcFitOptions fit;
    fit.num_inducing = sparse.num_inducing;
    absl::StatusOr<gp::FitcModel> model = gp::FitFitcModel(
        data.inputs, data.targets, hyperparameters, fit, sparse.inducing, sparse.rng, nullptr);
    if (!model.ok())
      return absl::Status(model.status().code(), absl::StrCat("FITC model: ", model.status().message()));
    out.sparse_ = std::make_unique<gp::FitcModel>(*std::move(model));
    out.model_dynamics_ = std::make_unique<estimators::FitcDynamics>(out.sparse_.get(), pool);
  } else {
    absl::StatusOr<gp::GpModel> model = gp::GpModel::Create(data.inputs, data.targets, hyperparameters, gp_options);
    if (!model.ok())
      return absl::Status(model.status().code(), absl::StrCat("GP model: ", model.status().message()));
    out.full_ = std::make_unique<gp::GpModel>(*std::move(model));
    out.model_dynamics_ = std::make_unique<estimators::GpDynamics>(out.full_.get(), pool);
  }
  out.raw_policy_ = policy->ParticleForm(pool);
  estimators::Problem& p = out.problem_;
  p.dynamics = out.model_dynamics_.get();
  if (!scene.dynamics_inputs.empty()) {
    // The GP sees a subset of the state (the unicycle's dyni); there are no
    // angle features then (TrialDynamicsInputs).
    TG_CHECK(angle_indices.empty());
    out.subset_dynamics_ = std::make_unique<estimators::InputSubsetDynamics>(
        out.model_dynamics_.get(), scene.dynamics_inputs);
    p.dynamics = out.subset_dynamics_.get();
  }
  p.policy = out.raw_policy_.get();
  if (!angle_indices.empty()) {
    out.feature_dynamics_ =
        std::make_unique<estimators::AngleFeatureDynamics>(out.model_dynamics_.get(), angle_indices);
    out.feature_policy_ =
        std::make_unique<estimators::AngleFeaturePolicy>(out.raw_policy_.get(), angle_indices);
    p.dynamics = out.feature_dynamics_.get();
    p.policy = out.feature_policy_.get();
  }
  p.cost = scene.cost.get();
  p.mu0 = scene.mu0;
  p.initial_std = scene.initial_std;
  p.horizon = scene.horizon;
  p.noise_variance_multiplier = noise_variance_multiplier;
  p.pool = pool;
  return out;
}

bool ModelProblem::jitter() const {
  if (full_ == nullptr) return false;
  for (int a = 0; a < full_->num_outputs(); ++a)
    if (full_->jitter(a) > 0) return true;
  return false;
}

absl::StatusOr<pilco::PilcoProblem> MakePilcoProblem(const tasks::StateCost& cost,
                                                     const Vector& mu0, const Vector& initial_std,
                                                     int horizon,
                                                     const std::vector<int>& angle_indices,
                                                     int num_basis, const Vector& max_control,
                                                     policy::PolicyClass policy_class,
                                                     const std::vector<int>& dynamics_inputs) {
  absl::StatusOr<gaussian::GaussianCost> gaussian_cost = cost.GaussianExpectation();
  if (!gaussian_cost.ok()) return gaussian_cost.status();
  pilco::PilcoProblem problem;
  problem.mu0 = mu0;
  problem.S0 = initial_std.array().square().matrix().asDiagonal();
  problem.horizon = horizon;
  problem.cost = std::make_shared<gaussian::GaussianCost>(*std::move(gaussian_cost));
  // One angle keeps the one-angle option (the form PILCO problems always had).
  if (angle_indices.size() == 1) {
    problem.propagation.angle_index = angle_indices[0];
  } else {
    problem.propagation.angle_indices = angle_indices;
  }
  // One control: max_force; several: max_controls (the GP takes u_1 .. u_F).
  if (max_control.size() == 1) {
    problem.propagation.max_force = max_control(0);
  } else {
    problem.propagation.max_controls = max_control;
  }
  problem.propagation.num_basis = num_basis;
  problem.propagation.policy_class = policy_class;
  problem.propagation.dynamics_inputs = dynamics_inputs;
  return problem;
}

}  // namespace totalgrad::learner
