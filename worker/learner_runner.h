// LearnerTrialRunner: the trials' JobRunner, over learner::RunTrial.
#ifndef TOTALGRAD_WORKER_LEARNER_RUNNER_H_
#define TOTALGRAD_WORKER_LEARNER_RUNNER_H_

#include "worker/job_runner.h"

namespace totalgrad::worker {

class LearnerTrialRunner final : public JobRunner {
 public:
  // Every trial runs on `threads_per_trial` threads (learner::RunOptions;
  // the numbers do not depend on it). >= 1.
  explicit LearnerTrialRunner(int threads_per_trial = 1) : threads_(threads_per_trial) {}
  // `job.options` go through learner::SetTrialOption, so the runner accepts
  // exactly what the core accepts; `job.resume_from` through
  // learner::DecodeCheckpoint and CheckResumable. Reports a checkpoint after
  // every episode (JobProgress::OnCheckpoint). Thread-safe (RunTrial keeps no
  // shared state).
  absl::StatusOr<JobOutcome> Run(const JobInput& job, JobProgress* progress) override;
  // learner::EstimateTrialCost of the whole trial (a resumed one too: an
  // upper bound), on one thread.
  std::optional<double> EstimateCpuSeconds(const JobInput& job) const override;

 private:
  int threads_;
};

}  // namespace totalgrad::worker

#endif  // TOTALGRAD_WORKER_LEARNER_RUNNER_H_
