#include "core/estimators/synthetic_problem.h"

#include <cmath>

#include "core/gp/training.h"

namespace totalgrad::estimators {

absl::StatusOr<std::unique_ptr<SyntheticProblem>> MakeSyntheticProblem(
    const SyntheticProblemOptions& options) {
  if (options.data < 2) return absl::InvalidArgumentError("synthetic problem: data must be >= 2");
  auto out = std::make_unique<SyntheticProblem>();
  absl::StatusOr<tasks::Scene> scene =
      tasks::MakeScene(options.scene, options.cost, options.horizon);
  if (!scene.ok()) return scene.status();
  out->scene = std::make_unique<tasks::Scene>(*std::move(scene));
  const tasks::Scene& sc = *out->scene;
  const auto* cartpole = dynamic_cast<const tasks::CartPole*>(sc.plant.get());
  if (cartpole == nullptr)
    return absl::InvalidArgumentError("synthetic problem: the scene must be a cart-pole scene");

  // Transitions from states spread over the swing-up region.
  Rng rng(options.seed, Stream::kStudy, 1);
  RowMatrix x(options.data, 5), y(options.data, 4);
  const double max_force = cartpole->params().max_force;
  for (int n = 0; n < options.data; ++n) {
    tasks::State s;
    s << rng.Uniform(-1.0, 1.0), rng.Uniform(-0.5, 2.0 * M_PI), rng.Uniform(-3.0, 3.0),
        rng.Uniform(-8.0, 8.0);
    const double f = rng.Uniform(-max_force, max_force);
    tasks::State next;
    absl::Status st = cartpole->Step(s, f, &next);
    if (!st.ok()) return st;
    x.row(n).head<4>() = s.transpose();
    x(n, 4) = f;
    for (int d = 0; d < 4; ++d) y(n, d) = next(d) - s(d) + 0.01 * rng.Normal();
  }
  gp::GpHyperparameters hyp = gp::InitialHyperparameters(x, y);
  if (options.train_iterations > 0) {
    gp::TrainingOptions training;
    training.max_iterations = options.train_iterations;
    absl::StatusOr<gp::TrainingSummary> summary = gp::TrainHyperparameters(x, y, training, &hyp);
    if (!summary.ok()) return summary.status();
  }
  gp::GpModelOptions model_options;
  model_options.variance_rank_tolerance = options.variance_rank_tolerance;
  absl::StatusOr<gp::GpModel> model = gp::GpModel::Create(x, y, hyp, model_options);
  if (!model.ok()) return model.status();
  out->model = std::make_unique<gp::GpModel>(*std::move(model));

  out->policy = std::make_unique<policy::RbfPolicy>(options.basis_functions, 4, max_force);
  Rng policy_rng(options.seed, Stream::kPolicyInit);
  out->policy->Initialize(sc.mu0, Vector::Constant(4, 1.0), 1.0, &policy_rng);

  out->dynamics = std::make_unique<GpDynamics>(out->model.get());
  out->controller = std::make_unique<RbfParticlePolicy>(out->policy.get());
  Problem& p = out->problem;
  p.dynamics = out->dynamics.get();
  p.policy = out->controller.get();
  p.cost = sc.cost.get();
  p.mu0 = sc.mu0;
  p.initial_std = sc.initial_std;
  p.horizon = options.horizon;
  p.noise_variance_multiplier = options.noise_variance_multiplier;
  return out;
}

}  // namespace totalgrad::estimators
