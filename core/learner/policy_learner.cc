#include "core/learner/policy_learner.h"

#include <utility>

#include "absl/strings/str_cat.h"
#include "core/gp/training.h"
#include "core/gaussian/angle_features.h"

namespace totalgrad::learner {

PolicyLearner::PolicyLearner(const TrialOptions& options, const tasks::Scene& scene,
                             std::vector<int> angles)
    : options_(options),
      scene_(scene),
      angles_(std::move(angles)),
      policy_(options.policy, options.basis_functions,
              gaussian::FeatureDim(scene.state_dim(), angles_), scene.max_control) {}

absl::StatusOr<GpTrainingSet> PolicyLearner::TrainModel(const Transitions& transitions,
                                                        int episode, EpisodeResult* result) {
  GpTrainingSet data = MakeGpTrainingSet(transitions, angles_, scene_.dynamics_inputs);
  if (!hyperparameters_) hyperparameters_ = gp::InitialHyperparameters(data.inputs, data.targets);
  absl::StatusOr<gp::TrainingSummary> training =
      gp::TrainHyperparameters(data.inputs, data.targets, options_.gp_training, &*hyperparameters_);
  if (!training.ok())
    return absl::Status(training.status().code(),
                        absl::StrCat("episode ", episode, ": GP training: ", training.status().message()));
  result->flags.gp_line_search_failures = training->line_search_failures;
  result->flags.gp_non_finite_evaluations = training->non_finite_evaluations;
  result->hyperparameters = *hyperparameters_;
  return data;
}

absl::Status PolicyLearner::Improve(const Transitions& data, int episode, TrialObserver* observer,
                                    PhaseClock* clock, EpisodeResult* result) {
  absl::StatusOr<GpTrainingSet> trained = TrainModel(data, episode, result);
  if (!trained.ok()) return trained.status();
  return ImprovePolicy(*trained, episode, observer, clock, result);
}

void PolicyLearner::SaveState(TrialCheckpoint* checkpoint) const {
  checkpoint->policy_parameters = policy_.parameters();
  checkpoint->hyperparameters = hyperparameters_;
  checkpoint->inducing_inputs = inducing_;
}

absl::Status PolicyLearner::RestoreState(const TrialCheckpoint& checkpoint) {
  if (checkpoint.policy_parameters.size() != policy_.num_parameters())
    return absl::InvalidArgumentError(absl::StrCat(
        "trial checkpoint: the policy has ", checkpoint.policy_parameters.size(),
        " parameters; this trial's has ", policy_.num_parameters()));
  policy_.set_parameters(checkpoint.policy_parameters);
  hyperparameters_ = checkpoint.hyperparameters;
  inducing_ = checkpoint.inducing_inputs;
  return absl::OkStatus();
}

absl::StatusOr<std::unique_ptr<PolicyLearner>> MakePolicyLearner(const TrialOptions& options,
                                                                 const tasks::Scene& scene,
                                                                 ThreadPool* pool) {
  if (options.method == estimators::Method::kPilco) return MakePilcoLearner(options, scene);
  return MakeParticleLearner(options, scene, pool);
}

}  // namespace totalgrad::learner
