// The seam between the worker runtime and the gradient-study code (issue 6):
// a StudyRunner runs one study job from its self-contained spec (the study
// file's JSON, snapshot inlined; io/study_file.h) and
// returns its rows. The real one (CoreStudyRunner) calls study::RunStudy;
// tests inject fakes.
//
// A study reports nothing while it runs: its rows are the result of the
// whole study, returned at the end and then sent by the runtime.
#ifndef TOTALGRAD_WORKER_STUDY_RUNNER_H_
#define TOTALGRAD_WORKER_STUDY_RUNNER_H_

#include <string>
#include <vector>

#include "absl/status/statusor.h"
#include "totalgrad/v1/types.pb.h"
#include "worker/trial_runner.h"

namespace totalgrad::worker {

// One row per study::CellResult and per study::ReferenceGradient, with
// `index` = the position in the study's result (job_id, attempt and study
// are left empty: the coordinator knows them).
struct StudyOutcome {
  std::vector<v1::StudyCellRow> cells;
  std::vector<v1::StudyReferenceRow> references;
};

class StudyRunner {
 public:
  virtual ~StudyRunner() = default;
  // Runs the study. `progress` is polled for cancellation (ShouldCancel;
  // OnEpisode is never called). Errors: InvalidArgument (the spec),
  // Cancelled (ShouldCancel), or the study's own failure, named. Must be safe
  // to call from several threads at once.
  virtual absl::StatusOr<StudyOutcome> Run(const std::string& spec_json,
                                           TrialProgress* progress) = 0;
};

// The real runner: study_command's parser and problem loader, then
// study::RunStudy on one thread (BLAS limited to one thread, as for trials).
class CoreStudyRunner final : public StudyRunner {
 public:
  absl::StatusOr<StudyOutcome> Run(const std::string& spec_json, TrialProgress* progress) override;
};

}  // namespace totalgrad::worker

#endif  // TOTALGRAD_WORKER_STUDY_RUNNER_H_
