// How a method turns a trial's data into a policy, one object per trial
// (its policy, GP hyperparameters and inducing inputs persist across
// episodes as warm starts). RunTrial (trial.cc) drives it; the particle
// methods' learner is in particle_learner.cc, PILCO's in pilco_learner.cc.
// Internal to core/learner.
//
// Thread safety: one learner per trial, used from the trial's thread.
#ifndef TOTALGRAD_CORE_LEARNER_POLICY_LEARNER_H_
#define TOTALGRAD_CORE_LEARNER_POLICY_LEARNER_H_

#include <memory>
#include <optional>

#include "absl/status/statusor.h"
#include "core/common/thread_pool.h"
#include "core/gp/gp.h"
#include "core/learner/checkpoint.h"
#include "core/learner/phase_clock.h"
#include "core/learner/problem_builder.h"
#include "core/learner/trial.h"
#include "core/learner/trial_policy.h"
#include "core/tasks/scene.h"

namespace totalgrad::learner {

class PolicyLearner {
 public:
  virtual ~PolicyLearner() = default;
  // Trains the GP's hyperparameters on `data` (TrainModel), then fits the
  // model, optimises the policy (ImprovePolicy) and fills the model- and
  // optimisation-related fields of *result, timing its phases with `clock`
  // (model, policy, prediction laps into result->timing). Errors name the
  // episode; Cancelled when the observer asked.
  absl::Status Improve(const Transitions& data, int episode, TrialObserver* observer,
                       PhaseClock* clock, EpisodeResult* result);
  // What carries over to the next episode (checkpoint.h), and back.
  virtual void SaveState(TrialCheckpoint* checkpoint) const;
  virtual absl::Status RestoreState(const TrialCheckpoint& checkpoint);

  // The current policy as a controller of the real plant (the scene's F
  // controls); it follows the policy's later changes (it holds a pointer to
  // it).
  tasks::MultiController Controller() const { return FeaturePolicyController(&policy_, angles_); }
  const Vector& Parameters() const { return policy_.parameters(); }

 protected:
  // angles: none (raw) or the scene's angles (sin, cos features).
  PolicyLearner(const TrialOptions& options, const tasks::Scene& scene, std::vector<int> angles);
  // The GP's training set from `data` (on angle features where angles_ is
  // not empty), its hyperparameters trained on it (warm-started from the
  // last episode's) and the training's flags recorded in *result.
  absl::StatusOr<GpTrainingSet> TrainModel(const Transitions& data, int episode,
                                           EpisodeResult* result);
  // Improve's method-specific part, after the hyperparameters are trained on
  // `training_set` (hyperparameters_ holds them).
  virtual absl::Status ImprovePolicy(const GpTrainingSet& training_set, int episode,
                                     TrialObserver* observer, PhaseClock* clock,
                                     EpisodeResult* result) = 0;

  const TrialOptions& options_;
  const tasks::Scene& scene_;
  const std::vector<int> angles_;
  TrialPolicy policy_;
  std::optional<gp::GpHyperparameters> hyperparameters_;
  RowMatrix inducing_;  // FITC inducing inputs of the last sparse fit (warm start)
};

// The learner of options.method: PILCO's, or the particle methods' with its
// estimator. `options` and `scene` must outlive it; `pool` (may be null)
// spreads the particle methods' work. Errors: InvalidArgument (estimator
// options, a cost without a closed form for PILCO), PILCO's initial policy.
absl::StatusOr<std::unique_ptr<PolicyLearner>> MakePolicyLearner(const TrialOptions& options,
                                                                 const tasks::Scene& scene,
                                                                 ThreadPool* pool);
absl::StatusOr<std::unique_ptr<PolicyLearner>> MakeParticleLearner(const TrialOptions& options,
                                                                   const tasks::Scene& scene,
                                                                   ThreadPool* pool);
absl::StatusOr<std::unique_ptr<PolicyLearner>> MakePilcoLearner(const TrialOptions& options,
                                                                const tasks::Scene& scene);

}  // namespace totalgrad::learner

#endif  // TOTALGRAD_CORE_LEARNER_POLICY_LEARNER_H_
