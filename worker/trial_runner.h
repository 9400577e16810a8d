// The seam between the worker runtime and the numerical core: a TrialRunner
// runs one trial from its options and reports each finished episode. The real
// one (learner_runner.h) calls learner::RunTrial; tests inject fakes, so the
// worker's networking logic is tested without running the core (the
// episode's record, core/learner/episode_record.h, is a header-only struct).
#ifndef TOTALGRAD_WORKER_TRIAL_RUNNER_H_
#define TOTALGRAD_WORKER_TRIAL_RUNNER_H_

#include <limits>
#include <string>
#include <utility>
#include <vector>

#include "absl/status/statusor.h"
#include "core/learner/episode_record.h"

namespace totalgrad::worker {

using OptionList = std::vector<std::pair<std::string, std::string>>;

// One finished episode: its record (learner::EpisodeSummary, the core's own;
// NaN: no value, e.g. the evaluation of episode 0) and the trial's details.
struct EpisodeOutcome : learner::EpisodeSummary {
  std::string details_json;  // JSON object: hyperparameters, numerical flags
};

struct TrialOutcome {
  bool success = false;
  double final_eval_cost = learner::EpisodeSummary::kNaN;
  int episodes = 0;  // episodes reported
};

class TrialProgress {
 public:
  virtual ~TrialProgress() = default;
  // Called once per finished episode, in order, on the trial's thread.
  virtual void OnEpisode(const EpisodeOutcome& episode) = 0;
  // Polled often; true asks the trial to stop (it then returns Cancelled).
  virtual bool ShouldCancel() = 0;
  // Called after each finished episode, right after OnEpisode, with the
  // trial's state in the versioned checkpoint encoding of
  // core/learner/checkpoint.h: what a later attempt resumes from. Default:
  // ignored.
  virtual void OnCheckpoint(int episode, int format_version, std::string data) {}
};

class TrialRunner {
 public:
  virtual ~TrialRunner() = default;
  // Runs one trial with `options` (applied in order to default options).
  // Must be safe to call from several threads at once (one trial each).
  // Errors: InvalidArgument (options), Cancelled (ShouldCancel), or the
  // trial's own failure (Internal, FailedPrecondition, ...), named.
  virtual absl::StatusOr<TrialOutcome> Run(const OptionList& options, TrialProgress* progress) = 0;
  // Resumes the trial from `checkpoint` (OnCheckpoint data of an earlier run
  // of the same trial and build): the restored episodes are reported again,
  // then the trial continues as if never interrupted. Returns
  // FailedPrecondition starting "cannot resume" before reporting anything if
  // the checkpoint cannot be used (the caller then starts over). Default:
  // ignores the checkpoint and runs from the start.
  virtual absl::StatusOr<TrialOutcome> Resume(const OptionList& options,
                                              const std::string& checkpoint,
                                              TrialProgress* progress) {
    return Run(options, progress);
  }
};

}  // namespace totalgrad::worker

#endif  // TOTALGRAD_WORKER_TRIAL_RUNNER_H_
