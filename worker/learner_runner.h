// LearnerTrialRunner: the real TrialRunner, over learner::RunTrial.
#ifndef TOTALGRAD_WORKER_LEARNER_RUNNER_H_
#define TOTALGRAD_WORKER_LEARNER_RUNNER_H_

#include "worker/trial_runner.h"

namespace totalgrad::worker {

class LearnerTrialRunner final : public TrialRunner {
 public:
  // Options go through learner::SetTrialOption, so the runner accepts exactly
  // what the core accepts. Thread-safe (RunTrial keeps no shared state).
  absl::StatusOr<TrialOutcome> Run(const OptionList& options, TrialProgress* progress) override;
};

}  // namespace totalgrad::worker

#endif  // TOTALGRAD_WORKER_LEARNER_RUNNER_H_
