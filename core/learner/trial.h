// A full policy-learning trial (the job a worker runs):
//
//   episode 0:      one random episode (force ~ U(-max_force, max_force)).
//   episode e>=1:   fit the GP on all data so far, optimise the policy
//                   (policy_steps gradient steps of `particles` particles with
//                   the chosen estimator, warm-started), run one real episode
//                   whose data are added, and evaluate the policy with
//                   eval_rollouts independent real episodes.
//
// Results stream out through a TrialObserver, one call per finished episode;
// the observer is also polled for cancellation. core knows nothing of how
// they are transported.
//
// Determinism: the same TrialOptions (including the seed) and the same build
// give the same numbers, bit for bit (one thread per trial; every random
// number comes from a named substream of the seed).
//
// Options: core/learner/trial_options.h. Problems (the GP's data, the model,
// the adapters, PILCO's problem): core/learner/problem_builder.h. The
// learners of the two method families: particle_learner.h, pilco_learner.h.
#ifndef TOTALGRAD_CORE_LEARNER_TRIAL_H_
#define TOTALGRAD_CORE_LEARNER_TRIAL_H_

#include <cstdint>
#include <limits>
#include <string>
#include <utility>
#include <vector>

#include "absl/status/statusor.h"
#include "core/gp/gp.h"
#include "core/learner/episode_record.h"
#include "core/learner/trajectory.h"
#include "core/learner/trial_options.h"

namespace totalgrad::learner {

struct TrialCheckpoint;  // core/learner/checkpoint.h

struct EpisodeFlags {
  int non_finite_gradients = 0;    // gradient estimates dropped for non-finite values
  int gp_line_search_failures = 0; // caught during hyperparameter training
  int gp_non_finite_evaluations = 0;
  bool zero_gradient = false;      // some estimate was exactly zero (e.g. saturated cost)
  bool gp_jitter = false;          // K needed jitter to factorise
};

// Where an episode's time went. CPU seconds are those of the trial's own
// threads (the calling thread plus its RunOptions::threads pool), so they are
// the episode's cost whatever else runs in the process; wall seconds are
// elapsed time. Phases: fitting the model (GP hyperparameters, and FITC
// inducing inputs where used), optimising the policy (the gradient steps, or
// PILCO's BFGS), the model-predicted cost of the optimised policy, the real
// episode whose data are added, and the evaluation episodes.
struct EpisodeTiming {
  double model_cpu = 0, model_wall = 0;
  double policy_cpu = 0, policy_wall = 0;
  int policy_steps = 0;  // gradient steps taken (0 for PILCO and episode 0)
  double prediction_cpu = 0, prediction_wall = 0;
  double real_episode_cpu = 0, real_episode_wall = 0;
  double evaluation_cpu = 0, evaluation_wall = 0;
  double total_cpu() const {
    return model_cpu + policy_cpu + prediction_cpu + real_episode_cpu + evaluation_cpu;
  }
  double total_wall() const {
    return model_wall + policy_wall + prediction_wall + real_episode_wall + evaluation_wall;
  }
};

// An episode's record (episode_record.h: episode, costs, optimisation_seconds,
// cpu_seconds = timing.total_cpu()) and what only the trial has.
struct EpisodeResult : EpisodeSummary {
  // A trial measures both times of every episode; episode 0 has no
  // optimisation, 0 s (checkpoints and stored rows hold 0, not "no value").
  EpisodeResult() {
    optimisation_seconds = 0;
    cpu_seconds = 0;
  }
  EpisodeTiming timing;
  gp::GpHyperparameters hyperparameters;  // of the GP used this episode (empty for 0)
  Vector policy_parameters;        // the optimised policy of this episode (empty for 0)
  EpisodeFlags flags;
  // PILCO only: the model's predicted cost mean and std per step t = 1..H.
  Vector predicted_cost_mean_per_step;
  Vector predicted_cost_std_per_step;
  // The real episode, the model's prediction of it and, on the last
  // episode, the rollout verdict's rollouts (trajectory.h). Stored apart
  // from the record's fields, as EncodeEpisodeTrajectories bytes.
  EpisodeTrajectories trajectories;
};

struct TrialSummary {
  std::vector<EpisodeResult> episodes;
  bool success = false;
  double final_eval_cost = EpisodeResult::kNaN;
};

// The state of a trial at one learned episode e, for gradient studies
// (core/study): the data the model of episode e was fitted on, its trained
// hyperparameters, and the policy before (the warm start) and after episode
// e's optimisation. Building the problem from them (learner::ModelProblem)
// reproduces the particle methods' model of episode e bit for bit when it was
// the full GP on the raw state (core/study refuses sincos snapshots); a FITC
// model (gp_inducing, PILCO's or a particle method's) is not kept, and
// core/study refuses snapshots whose model was sparse.
struct TrialSnapshot {
  int episode = 0;
  // The trial's options as TrialOptionPairs (so that scene, cost, horizon,
  // basis functions and angle features can be rebuilt with SetTrialOption).
  std::vector<std::pair<std::string, std::string>> options;
  RowMatrix states;       // N x D, observed states x_t of every transition so far
  Vector forces;          // N F, the controls applied at x_t, transition-major
  RowMatrix next_states;  // N x D, observed x_{t+1}
  gp::GpHyperparameters hyperparameters;  // of episode e's model (inputs: angle_features)
  Vector policy_parameters_before;  // the policy entering episode e's optimisation
  Vector policy_parameters;         // the optimised policy of episode e
};

class TrialObserver {
 public:
  virtual ~TrialObserver() = default;
  // Called once per finished episode, in order, from the trial's thread.
  virtual void OnEpisode(const EpisodeResult& result) = 0;
  // Polled regularly (at least once per policy gradient step); true stops the
  // trial, which then returns CancelledError.
  virtual bool ShouldCancel() { return false; }
  // Called after every policy gradient step with the objective J estimated by
  // that step's forward pass and the norm of the parameter change (for
  // progress displays and optimiser diagnostics). Default: nothing.
  virtual void OnPolicyStep(int episode, int step, double objective, double step_norm) {}
  // Snapshots: asked once per learned episode before its optimisation; when
  // true, OnSnapshot is called after the optimisation and before OnEpisode.
  // Default: no snapshots (nothing is copied).
  virtual bool WantsSnapshot(int episode) { return false; }
  virtual void OnSnapshot(const TrialSnapshot& snapshot) {}
  // Checkpoints (core/learner/checkpoint.h): asked once per trial; when true,
  // OnCheckpoint is called after every finished episode, right after its
  // OnEpisode, with everything the next episode reads. Default: none.
  virtual bool WantsCheckpoints() { return false; }
  virtual void OnCheckpoint(const TrialCheckpoint& checkpoint) {}
};

// How a trial is executed, as opposed to what it computes: nothing here
// changes a number of the trial.
struct RunOptions {
  // Threads of the trial (the caller's plus threads - 1 started for it):
  // the GP's outputs and fixed particle blocks are spread over them
  // (core/common/thread_pool.h), so the results are the same bits for any
  // value. >= 1.
  int threads = 1;
};

// Runs the trial. `observer` may be null. Sets the process's BLAS to one
// thread (core/common/blas.h), so the numbers never depend on the core
// count. Errors: InvalidArgument (bad options), Cancelled, Internal (a numerical failure, named, e.g. the plant
// integrator failing or a non-finite cost), FailedPrecondition (GP could not
// be factorised).
absl::StatusOr<TrialSummary> RunTrial(const TrialOptions& options, TrialObserver* observer,
                                      const RunOptions& run = RunOptions());
// Resumes a trial from a checkpoint of it (`resume_from` may be null: a
// fresh trial): episodes 0..resume_from->episode are reported to the
// observer again from the checkpoint (OnEpisode, in order; no checkpoint
// for them), then the trial continues with the next episode and gives the
// same numbers as an uninterrupted run, bit for bit. InvalidArgument if the
// checkpoint is not of this trial (learner::CheckResumable).
absl::StatusOr<TrialSummary> RunTrial(const TrialOptions& options, TrialObserver* observer,
                                      const TrialCheckpoint* resume_from,
                                      const RunOptions& run = RunOptions());

}  // namespace totalgrad::learner

#endif  // TOTALGRAD_CORE_LEARNER_TRIAL_H_
