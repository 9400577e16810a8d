// CoreStudyRunner: the study jobs' JobRunner (issue 6), over study::RunStudy.
// It runs one study job from its self-contained spec (JobInput::spec_json:
// the study file's JSON, snapshot inlined; io/study_file.h) and returns the
// study's rows, the core's records, in the JobOutcome: a study reports
// nothing while it runs.
#ifndef TOTALGRAD_WORKER_STUDY_RUNNER_H_
#define TOTALGRAD_WORKER_STUDY_RUNNER_H_

#include "worker/job_runner.h"

namespace totalgrad::worker {

// study_command's parser and problem loader, then study::RunStudy on one
// thread (BLAS limited to one thread, as for trials). `progress` is polled
// for cancellation (ShouldCancel; OnEpisode is never called). Errors:
// InvalidArgument (the spec, or one naming a snapshot file), Cancelled, or
// the study's own failure, named. Thread-safe.
class CoreStudyRunner final : public JobRunner {
 public:
  absl::StatusOr<JobOutcome> Run(const JobInput& job, JobProgress* progress) override;
};

}  // namespace totalgrad::worker

#endif  // TOTALGRAD_WORKER_STUDY_RUNNER_H_
