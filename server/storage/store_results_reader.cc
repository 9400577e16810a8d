#include "server/storage/store_results_reader.h"

#include <map>

#include "absl/strings/str_cat.h"

namespace totalgrad::storage {

absl::StatusOr<std::vector<results::CompletedTrial>> StoreResultsReader::CompletedTrials(
    const std::string& sweep) {
  // Results first: every job they name is completed before the jobs are
  // listed (a job never leaves the completed state except by retry of a
  // failed one, which is not completed).
  absl::StatusOr<std::vector<results::CompletedTrial>> trials = store_->ListTrialResults(sweep);
  if (!trials.ok()) return trials.status();
  std::map<int64_t, record::TextPairs> options_of;
  JobFilter filter;
  filter.sweep_name = sweep;
  filter.states = {JobState::kCompleted};
  filter.limit = 1000;
  while (true) {
    absl::StatusOr<std::vector<JobRecord>> page = store_->ListJobs(filter);
    if (!page.ok()) return page.status();
    for (JobRecord& job : *page) options_of[job.id] = std::move(job.options);
    if (static_cast<int>(page->size()) < filter.limit) break;
    filter.after_job_id = page->back().id;
  }
  if (absl::Status attached = results::AttachOptions(sweep, std::move(options_of), &*trials);
      !attached.ok()) {
    return attached;
  }
  return trials;
}

}  // namespace totalgrad::storage
