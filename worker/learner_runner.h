// LearnerTrialRunner: the real TrialRunner, over learner::RunTrial.
#ifndef TOTALGRAD_WORKER_LEARNER_RUNNER_H_
#define TOTALGRAD_WORKER_LEARNER_RUNNER_H_

#include <string>

#include "worker/trial_runner.h"

namespace totalgrad::learner {
struct EpisodeResult;  // core/learner/trial.h; not included, so that users of
                       // this header need not see Eigen
}  // namespace totalgrad::learner

namespace totalgrad::worker {

class LearnerTrialRunner final : public TrialRunner {
 public:
  // Every trial runs on `threads_per_trial` threads (learner::RunOptions;
  // the numbers do not depend on it). >= 1.
  explicit LearnerTrialRunner(int threads_per_trial = 1) : threads_(threads_per_trial) {}
  // Options go through learner::SetTrialOption, so the runner accepts exactly
  // what the core accepts. Thread-safe (RunTrial keeps no shared state).
  absl::StatusOr<TrialOutcome> Run(const OptionList& options, TrialProgress* progress) override;
  // learner::DecodeCheckpoint + CheckResumable, then RunTrial from it.
  absl::StatusOr<TrialOutcome> Resume(const OptionList& options, const std::string& checkpoint,
                                      TrialProgress* progress) override;
  // Both report a checkpoint after every episode (TrialProgress::OnCheckpoint).

 private:
  int threads_;
};

}  // namespace totalgrad::worker

#endif  // TOTALGRAD_WORKER_LEARNER_RUNNER_H_
