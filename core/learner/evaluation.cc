#include "core/learner/evaluation.h"

#include <algorithm>
#include <cmath>

#include "absl/strings/str_cat.h"
#include "core/common/rng.h"
#include "core/learner/problem_builder.h"
#include "core/pilco/angle_features.h"
#include "core/policy/rbf_policy.h"

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

absl::StatusOr<PolicyEvaluation> EvaluatePolicy(const TrialOptions& options,
                                                const Vector& policy_parameters, int episode,
                                                int rollouts, bool keep_rollouts) {
  absl::Status valid = options.Validate();
  if (!valid.ok()) return valid;
  if (rollouts < 1) return absl::InvalidArgumentError("rollouts must be >= 1");
  if (episode < 0) return absl::InvalidArgumentError("episode must be >= 0");
  absl::StatusOr<tasks::Scene> scene = tasks::MakeScene(options.scene);
  if (!scene.ok()) return scene.status();
  std::vector<int> angles = FeatureAngles(options, *scene);
  policy::RbfPolicy policy(options.basis_functions, pilco::FeatureDim(scene->state_dim(), angles),
                           scene->max_control);
  if (policy_parameters.size() != policy.num_parameters()) {
    return absl::InvalidArgumentError(absl::StrCat(
        "the policy has ", policy_parameters.size(), " parameters; ",
        estimators::MethodName(options.method), " with ", options.basis_functions,
        " basis functions and angle_features=",
        EnumName(AngleFeaturesNames(), options.angle_features), " has ", policy.num_parameters()));
  }
  policy.set_parameters(policy_parameters);
  return EvaluateController(*scene, FeaturePolicyController(&policy, std::move(angles)), options.seed,
                            episode, rollouts, keep_rollouts);
}

}  // namespace totalgrad::learner
