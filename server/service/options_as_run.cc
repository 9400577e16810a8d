#include "server/service/options_as_run.h"

#include "absl/strings/str_cat.h"
#include "core/learner/trial_options.h"

namespace totalgrad::service {

absl::Status SetOptionsAsRun(storage::ImportedJob* job) {
  if (job->record.kind != storage::JobKind::kTrial ||
      job->record.state != storage::JobState::kCompleted || job->record.options.empty()) {
    return absl::OkStatus();
  }
  absl::StatusOr<learner::TrialOptions> ran =
      learner::TrialOptionsFromStoredPairs(job->record.options);
  if (!ran.ok()) {
    return absl::InvalidArgumentError(absl::StrCat(
        "archive: job ", job->record.method, " seed ", job->record.seed,
        job->record.variant.empty() ? "" : " (" + job->record.variant + ")",
        ": its options do not read with this build (", ran.status().message(),
        "); import the archive with the build that wrote it (its exported_by)"));
  }
  job->options_as_run = learner::TrialOptionPairs(*ran);
  return absl::OkStatus();
}

}  // namespace totalgrad::service
