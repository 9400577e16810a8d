#include "server/storage/store_results_reader.h"

#include <map>

#include "absl/strings/str_cat.h"

namespace totalgrad::storage {

absl::StatusOr<std::vector<results::CompletedTrial>> StoreResultsReader::CompletedTrials(
    const std::string& sweep) {
  // Results first: every job they name is completed before the jobs are
  // listed (a job never leaves the completed state except by retry of a
  // failed one, which is not completed).
  absl::StatusOr<std::vector<TrialResultRecord>> completed = store_->ListTrialResults(sweep);
  if (!completed.ok()) return completed.status();
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
  std::vector<results::CompletedTrial> trials;
  trials.reserve(completed->size());
  for (const TrialResultRecord& result : *completed) {
    auto options = options_of.find(result.job_id);
    if (options == options_of.end()) {
      return absl::InternalError(absl::StrCat("job ", result.job_id, " of sweep ", sweep,
                                              " has a result but is not listed as completed"));
    }
    results::CompletedTrial trial;
    trial.method = result.method;
    trial.seed = result.seed;
    trial.variant = result.variant;
    trial.success = result.success;
    trial.final_eval_cost = result.final_eval_cost;
    trial.held_fraction = result.held_fraction;
    trial.sweep = sweep;
    trial.job_id = result.job_id;
    trial.attempt = result.attempt;
    trial.episodes = result.episodes;
    trial.options = std::move(options->second);
    trials.push_back(std::move(trial));
  }
  return trials;
}

}  // namespace totalgrad::storage
