// Evaluating a policy on the real plant, as a trial evaluates the policy of
// each learned episode: `eval_rollouts` independent episodes whose start
// states and observation noise come from the evaluation streams of (seed,
// episode, rollout), so the same policy, seed and episode give the same
// numbers bit for bit whoever evaluates it (RunTrial, EvaluatePolicy).
//
// Thread safety: free functions and plain data.
#ifndef TOTALGRAD_CORE_LEARNER_EVALUATION_H_
#define TOTALGRAD_CORE_LEARNER_EVALUATION_H_

#include <cstdint>
#include <vector>

#include "absl/status/statusor.h"
#include "core/common/types.h"
#include "core/learner/trial_options.h"
#include "core/tasks/scene.h"

namespace totalgrad::learner {

struct PolicyEvaluation {
  std::vector<double> costs;  // one per rollout
  double mean = 0;
  double std = 0;  // sample standard deviation (0 for one rollout)
  // The rollouts themselves (true states, observations, controls, per-step
  // costs), in rollout order; filled only when the caller asks for them
  // (keep_rollouts), empty otherwise: a trial's evaluation keeps none.
  std::vector<tasks::Episode> rollouts;
};

// `rollouts` real episodes of `scene` under `controller`; rollout r of
// episode e draws its start state from the stream (seed, kEvaluation, 2 i)
// and its noise from (seed, kEvaluation, 2 i + 1), i = e * 100000 + r.
// Errors: Internal naming the rollout when the plant fails (rollouts >= 1 is
// the caller's to check). `keep_rollouts` also returns every rollout
// (PolicyEvaluation::rollouts); the numbers do not depend on it.
absl::StatusOr<PolicyEvaluation> EvaluateController(const tasks::Scene& scene,
                                                    const tasks::MultiController& controller,
                                                    uint64_t seed, int episode, int rollouts,
                                                    bool keep_rollouts = false);

// A trial's policy evaluated on the real plant, as RunTrial evaluates the
// policy of episode `episode`: for the trial's own seed and episode the mean
// is bit for bit the trial's eval_cost_mean. `options` give the scene, cost,
// method and angle features (which decide the policy's input features) and
// the seed; `policy_parameters` must have the size of that policy.
// InvalidArgument for bad options, sizes, episode < 0 or rollouts < 1;
// Internal if the plant fails.
absl::StatusOr<PolicyEvaluation> EvaluatePolicy(const TrialOptions& options,
                                                const Vector& policy_parameters, int episode,
                                                int rollouts, bool keep_rollouts = false);

}  // namespace totalgrad::learner

#endif  // TOTALGRAD_CORE_LEARNER_EVALUATION_H_
