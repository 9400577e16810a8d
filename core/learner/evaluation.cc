#include "core/learner/evaluation.h"

#include <utility>

#include <algorithm>
#include <cmath>
#include <memory>

#include "absl/strings/str_cat.h"
#include "core/common/check.h"
#include "core/common/rng.h"
#include "core/learner/problem_builder.h"
#include "core/gaussian/angle_features.h"
#include "core/learner/trial_policy.h"

namespace totalgrad::learner {

absl::StatusOr<PolicyEvaluation> EvaluateController(const tasks::Scene& scene,
                                                    const tasks::MultiController& controller,
                                                    uint64_t seed, int episode, int rollouts,
                                                    bool keep_rollouts) {
  PolicyEvaluation evaluation;
  double sum = 0, sum_sq = 0;
  for (int r = 0; r < rollouts; ++r) {
    const uint64_t index = static_cast<uint64_t>(episode) * 100000ULL + static_cast<uint64_t>(r);
    Rng start_rng(seed, Stream::kEvaluation, 2 * index);
    Rng noise_rng(seed, Stream::kEvaluation, 2 * index + 1);
    tasks::Episode run;
    absl::Status status = tasks::RunEpisode(scene, controller, &start_rng, &noise_rng, &run);
    if (!status.ok()) return absl::InternalError(absl::StrCat("rollout ", r, ": ", status.message()));
    evaluation.costs.push_back(run.total_cost);
    sum += run.total_cost;
    sum_sq += run.total_cost * run.total_cost;
    if (keep_rollouts) evaluation.rollouts.push_back(std::move(run));
  }
  const double n = rollouts;
  evaluation.mean = sum / n;
  evaluation.std = n > 1 ? std::sqrt(std::max(0.0, (sum_sq - sum * sum / n) / (n - 1))) : 0.0;
  return evaluation;
}

bool RolloutHeld(const tasks::Scene& scene, const tasks::Episode& rollout, double distance,
                 int hold_steps) {
  // An episode that reached the scene's end (the unicycle fell) did not
  // hold, however close its last kept states were.
  if (rollout.ended) return false;
  const int horizon = static_cast<int>(rollout.states.rows()) - 1;
  TG_CHECK(hold_steps >= 1 && hold_steps <= horizon);
  for (int t = horizon - hold_steps + 1; t <= horizon; ++t) {
    const Vector x = rollout.states.row(t).transpose();
    // Written as "not within" so that a NaN distance is not held.
    if (!(tasks::GoalDistance(scene, x) <= distance)) return false;
  }
  return true;
}

absl::StatusOr<RolloutClassification> ClassifyController(const tasks::Scene& scene,
                                                         const tasks::MultiController& controller,
                                                         uint64_t seed, int episode, int rollouts,
                                                         double distance, int hold_steps,
                                                         std::vector<tasks::Episode>* classified) {
  if (rollouts < 1) return absl::InvalidArgumentError("verdict rollouts must be >= 1");
  if (!(distance > 0) || !std::isfinite(distance))
    return absl::InvalidArgumentError("verdict distance must be finite and > 0");
  if (hold_steps < 1 || hold_steps > scene.horizon) {
    return absl::InvalidArgumentError(absl::StrCat("verdict hold of ", hold_steps,
                                                   " steps is outside 1..", scene.horizon));
  }
  absl::StatusOr<PolicyEvaluation> evaluation =
      EvaluateController(scene, controller, seed, episode, rollouts, /*keep_rollouts=*/true);
  if (!evaluation.ok()) return evaluation.status();
  RolloutClassification classification;
  classification.rollouts = rollouts;
  for (const tasks::Episode& run : evaluation->rollouts)
    if (RolloutHeld(scene, run, distance, hold_steps)) ++classification.held;
  if (classified != nullptr) *classified = std::move(evaluation->rollouts);
  return classification;
}

namespace {

// The scene, the policy with `policy_parameters` and its controller, as a
// trial of `options` runs its policy.
struct PolicyOnScene {
  tasks::Scene scene;
  std::unique_ptr<TrialPolicy> policy;
  tasks::MultiController controller;
};

absl::StatusOr<PolicyOnScene> MakePolicyOnScene(const TrialOptions& options,
                                                const Vector& policy_parameters) {
  absl::StatusOr<tasks::Scene> scene = tasks::MakeScene(options.scene);
  if (!scene.ok()) return scene.status();
  std::vector<int> angles = FeatureAngles(options, *scene);
  auto policy = std::make_unique<TrialPolicy>(options.policy, options.basis_functions,
                                              gaussian::FeatureDim(scene->state_dim(), angles),
                                              scene->max_control);
  if (policy_parameters.size() != policy->num_parameters()) {
    return absl::InvalidArgumentError(absl::StrCat(
        "the policy has ", policy_parameters.size(), " parameters; ",
        estimators::MethodName(options.method), " with ",
        options.policy == policy::PolicyClass::kLinear
            ? std::string("the linear policy")
            : absl::StrCat(options.basis_functions, " basis functions"),
        " and angle_features=",
        EnumName(AngleFeaturesNames(), options.angle_features), " has ", policy->num_parameters()));
  }
  policy->set_parameters(policy_parameters);
  PolicyOnScene made{*std::move(scene), std::move(policy), {}};
  made.controller = FeaturePolicyController(made.policy.get(), std::move(angles));
  return made;
}

}  // namespace

absl::StatusOr<RolloutClassification> ClassifyPolicy(const TrialOptions& options,
                                                     const Vector& policy_parameters, int episode) {
  absl::Status valid = options.Validate();
  if (!valid.ok()) return valid;
  if (options.verdict_rollouts < 1)
    return absl::InvalidArgumentError("verdict_rollouts is 0: the options ask for no rollout verdict");
  if (episode < 0) return absl::InvalidArgumentError("episode must be >= 0");
  absl::StatusOr<PolicyOnScene> made = MakePolicyOnScene(options, policy_parameters);
  if (!made.ok()) return made.status();
  return ClassifyController(made->scene, made->controller, options.seed, episode,
                            options.verdict_rollouts, options.verdict_distance,
                            VerdictHoldSteps(options, made->scene));
}

absl::StatusOr<PolicyEvaluation> EvaluatePolicy(const TrialOptions& options,
                                                const Vector& policy_parameters, int episode,
                                                int rollouts, bool keep_rollouts) {
  absl::Status valid = options.Validate();
  if (!valid.ok()) return valid;
  if (rollouts < 1) return absl::InvalidArgumentError("rollouts must be >= 1");
  if (episode < 0) return absl::InvalidArgumentError("episode must be >= 0");
  absl::StatusOr<PolicyOnScene> made = MakePolicyOnScene(options, policy_parameters);
  if (!made.ok()) return made.status();
  return EvaluateController(made->scene, made->controller, options.seed, episode, rollouts,
                            keep_rollouts);
}

}  // namespace totalgrad::learner
