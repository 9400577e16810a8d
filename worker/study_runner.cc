#include "worker/study_runner.h"

#include <utility>

#include <nlohmann/json.hpp>

#include "absl/strings/str_cat.h"
#include "io/study_file.h"
#include "core/common/blas.h"
#include "core/study/study.h"

namespace totalgrad::worker {

absl::StatusOr<JobOutcome> CoreStudyRunner::Run(const JobInput& job, JobProgress* progress) {
  const nlohmann::json doc =
      nlohmann::json::parse(job.spec_json, nullptr, /*allow_exceptions=*/false);
  if (doc.is_discarded() || !doc.is_object()) {
    return absl::InvalidArgumentError("study job: the spec is not a JSON object");
  }
  absl::StatusOr<io::StudySpec> spec = io::ParseStudySpec(doc, /*base_dir=*/"");
  if (!spec.ok()) {
    return absl::InvalidArgumentError(absl::StrCat("study job: ", spec.status().message()));
  }
  if (!spec->snapshot_file.empty()) {
    return absl::InvalidArgumentError(absl::StrCat(
        "study job: problem.snapshot names a file ('", spec->snapshot_file,
        "'); a study job carries its snapshot inline"));
  }
  absl::StatusOr<std::unique_ptr<study::FrozenProblem>> problem = io::LoadStudyProblem(*spec);
  if (!problem.ok()) {
    return absl::Status(problem.status().code(),
                        absl::StrCat("study job: ", problem.status().message()));
  }
  SetBlasThreads(1);  // timings are of single-threaded runs, as in `totalgrad study`
  absl::StatusOr<study::StudyResult> result = study::RunStudy(
      **problem, spec->options, /*progress=*/nullptr,
      [progress] { return progress != nullptr && progress->ShouldCancel(); });
  if (!result.ok()) return result.status();

  // The rows are the core records, each keyed by its position in the result.
  JobOutcome outcome;
  outcome.study_cells = std::move(result->cells);
  outcome.study_references = std::move(result->references);
  return outcome;
}

}  // namespace totalgrad::worker
