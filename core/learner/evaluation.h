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

// The rollout verdict (TrialOptions::verdict_*): whether each rollout of a
// policy "swung up and held".
//
// A rollout is held when tasks::GoalDistance of each of its last
// `hold_steps` post-step true states x_{H-hold_steps+1}..x_H is at most
// `distance` (on the cart-pole: the pole tip within `distance` metres of the
// upright tip above the target for the last hold_steps * dt seconds). A
// policy that swings up and then lets the pole fall is not held, however
// low its summed cost. A rollout that reached the scene's episode end (the
// unicycle fell: tasks::Episode::ended) is not held. On the unicycle the
// distance is that of loss_unicycle (tasks::UnicycleUprightDistance).
bool RolloutHeld(const tasks::Scene& scene, const tasks::Episode& rollout, double distance,
                 int hold_steps);

struct RolloutClassification {
  int rollouts = 0;
  int held = 0;
  double held_fraction() const { return rollouts > 0 ? static_cast<double>(held) / rollouts : 0.0; }
  // The trial's rollout verdict: held in at least half of the rollouts.
  bool verdict() const { return rollouts > 0 && 2 * held >= rollouts; }
};

// `rollouts` rollouts of `controller` drawn as EvaluateController draws
// episode `episode`'s (so the first eval_rollouts are that evaluation's own),
// each classified by RolloutHeld. Errors: InvalidArgument for rollouts < 1,
// distance not > 0 or hold_steps outside 1..horizon; Internal naming the
// rollout when the plant fails. `classified` (may be null) receives the
// rollouts themselves, in order.
absl::StatusOr<RolloutClassification> ClassifyController(const tasks::Scene& scene,
                                                         const tasks::MultiController& controller,
                                                         uint64_t seed, int episode, int rollouts,
                                                         double distance, int hold_steps,
                                                         std::vector<tasks::Episode>* classified = nullptr);

// A trial's policy classified as RunTrial classifies its final policy, by the
// rule of `options` (verdict_rollouts, verdict_distance,
// verdict_hold_seconds; InvalidArgument when verdict_rollouts is 0), for
// any episode's policy, e.g. a snapshot's (`totalgrad evaluate --classify`).
// Same errors as EvaluatePolicy.
absl::StatusOr<RolloutClassification> ClassifyPolicy(const TrialOptions& options,
                                                     const Vector& policy_parameters, int episode);

}  // namespace totalgrad::learner

#endif  // TOTALGRAD_CORE_LEARNER_EVALUATION_H_
