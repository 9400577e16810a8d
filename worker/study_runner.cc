#include "worker/study_runner.h"

#include <nlohmann/json.hpp>

#include "absl/strings/str_cat.h"
#include "io/study_file.h"
#include "core/common/blas.h"
#include "core/study/study.h"
#include "server/common/record_proto.h"

namespace totalgrad::worker {

absl::StatusOr<StudyOutcome> CoreStudyRunner::Run(const std::string& spec_json,
                                                  TrialProgress* progress) {
  const nlohmann::json doc = nlohmann::json::parse(spec_json, nullptr, /*allow_exceptions=*/false);
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

  // The rows are the core records converted by name (record_proto.h), each
  // keyed by its position in the result.
  StudyOutcome outcome;
  for (size_t i = 0; i < result->references.size(); ++i) {
    v1::StudyReferenceRow row;
    row.set_index(static_cast<int>(i));
    record_proto::RecordToProto(study::ReferenceFields(), result->references[i], &row);
    outcome.references.push_back(std::move(row));
  }
  for (size_t i = 0; i < result->cells.size(); ++i) {
    v1::StudyCellRow row;
    row.set_index(static_cast<int>(i));
    record_proto::RecordToProto(study::CellFields(), result->cells[i], &row);
    outcome.cells.push_back(std::move(row));
  }
  return outcome;
}

}  // namespace totalgrad::worker
