// PILCO's learner: analytic moment matching and BFGS (core/pilco) on the
// features the angle option selects, with FITC once the data exceed the
// inducing-input count (InducingInputs: 300 by default, as PILCO).
#include <memory>
#include <utility>

#include "absl/strings/str_cat.h"
#include "core/common/rng.h"
#include "core/learner/policy_learner.h"
#include "core/pilco/pilco.h"

namespace totalgrad::learner {
namespace {

// PILCO's moment-matched prediction of the state (its first d dimensions:
// the propagated vector may carry more), t = 0..H.
void PredictedStates(const pilco::Trajectory& prediction, int d, EpisodeTrajectories* out) {
  const int steps = static_cast<int>(prediction.means.size());
  out->predicted_mean.resize(steps, d);
  out->predicted_std.resize(steps, d);
  for (int t = 0; t < steps; ++t) {
    out->predicted_mean.row(t) = prediction.means[t].head(d).transpose();
    out->predicted_std.row(t) =
        prediction.covs[t].diagonal().head(d).cwiseMax(0.0).cwiseSqrt().transpose();
  }
}

class PilcoLearner final : public PolicyLearner {
 public:
  PilcoLearner(const TrialOptions& options, const tasks::Scene& scene, std::vector<int> angles,
               pilco::PilcoProblem problem)
      : PolicyLearner(options, scene, std::move(angles)), problem_(std::move(problem)) {}

  absl::Status Init() {
    Rng init_rng(options_.seed, Stream::kPolicyInit);
    absl::StatusOr<Vector> params = pilco::InitialPolicyParameters(problem_, &init_rng);
    if (!params.ok()) return params.status();
    policy_.set_parameters(*params);
    return absl::OkStatus();
  }

  absl::Status ImprovePolicy(const GpTrainingSet& training_set, int e, TrialObserver* observer,
                             PhaseClock* clock, EpisodeResult* result) override {
    EpisodeTiming& timing = result->timing;
    pilco::DynamicsModelOptions model_options;
    model_options.num_inducing = InducingInputs(options_);
    Rng inducing_rng(options_.seed, Stream::kGpInit, static_cast<uint64_t>(e));
    pilco::DynamicsModelReport report;
    absl::StatusOr<pilco::GaussianInputGp> model =
        pilco::BuildDynamicsModel(training_set.inputs, training_set.targets, *hyperparameters_,
                                  model_options, &inducing_, &inducing_rng, &report);
    if (!model.ok())
      return absl::Status(model.status().code(),
                          absl::StrCat("episode ", e, ": PILCO model: ", model.status().message()));
    clock->Lap(&timing.model_cpu, &timing.model_wall);
    pilco::PilcoOptions pilco_options;
    pilco_options.bfgs.max_line_searches = PilcoLineSearches(options_);
    pilco_options.bfgs.max_evaluations_per_line_search = PilcoEvaluationsPerLineSearch(options_);
    bool cancelled = false;
    pilco_options.bfgs.should_stop = [observer, &cancelled]() {
      cancelled = observer != nullptr && observer->ShouldCancel();
      return cancelled;
    };
    Vector params = policy_.parameters();
    absl::StatusOr<pilco::PilcoResult> optimised = pilco::OptimizePolicy(*model, problem_, pilco_options, &params);
    if (cancelled) return absl::CancelledError(absl::StrCat("trial cancelled in episode ", e));
    if (!optimised.ok())
      return absl::Status(optimised.status().code(),
                          absl::StrCat("episode ", e, ": PILCO optimisation: ", optimised.status().message()));
    policy_.set_parameters(params);
    clock->Lap(&timing.policy_cpu, &timing.policy_wall);
    result->predicted_cost = optimised->prediction.total_cost;
    result->predicted_cost_mean_per_step = optimised->prediction.cost_mean;
    result->predicted_cost_std_per_step = optimised->prediction.cost_std;
    PredictedStates(optimised->prediction, scene_.state_dim(), &result->trajectories);
    result->policy_parameters = params;
    return absl::OkStatus();
  }

 private:
  pilco::PilcoProblem problem_;
};

}  // namespace

absl::StatusOr<std::unique_ptr<PolicyLearner>> MakePilcoLearner(const TrialOptions& options,
                                                                const tasks::Scene& scene) {
  std::vector<int> angles = FeatureAngles(options, scene);
  // PILCO's moment matching (core/pilco) takes any number of angles and of
  // controls.
  absl::StatusOr<pilco::PilcoProblem> problem =
      MakePilcoProblem(*scene.cost, scene.mu0, scene.initial_std, scene.horizon, angles,
                       options.basis_functions, scene.max_control, options.policy,
                       scene.dynamics_inputs);
  if (!problem.ok()) return problem.status();
  auto learner = std::make_unique<PilcoLearner>(options, scene, std::move(angles), *std::move(problem));
  if (absl::Status status = learner->Init(); !status.ok()) return status;
  return std::unique_ptr<PolicyLearner>(std::move(learner));
}

}  // namespace totalgrad::learner
