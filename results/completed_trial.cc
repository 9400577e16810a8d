#include "results/completed_trial.h"

#include "absl/status/status.h"
#include "absl/strings/str_cat.h"

namespace totalgrad::results {

const record::FieldTable<CompletedTrial>& CompletedTrialResultFields() {
  using T = CompletedTrial;
  static const record::FieldTable<T> table = {
      {"job_id", &T::job_id},
      {"method", &T::method},
      {"seed", &T::seed},
      {"variant", &T::variant},
      {"attempt", &T::attempt},
      {"success", &T::success},
      {"final_eval_cost", &T::final_eval_cost},
      {"episodes", &T::episodes},
      {"held_fraction", &T::held_fraction},
  };
  return table;
}

const record::FieldTable<CompletedTrial>& CompletedTrialFields() {
  using T = CompletedTrial;
  static const record::FieldTable<T> table = [] {
    record::FieldTable<T> all = {{"sweep", &T::sweep}};
    for (const record::Field<T>& field : CompletedTrialResultFields()) all.push_back(field);
    all.push_back({"options", &T::options});
    return all;
  }();
  return table;
}

absl::Status AttachOptions(const std::string& sweep,
                           std::map<int64_t, record::TextPairs> options_of,
                           std::vector<CompletedTrial>* trials) {
  for (CompletedTrial& trial : *trials) {
    auto options = options_of.find(trial.job_id);
    if (options == options_of.end()) {
      return absl::InternalError(absl::StrCat("job ", trial.job_id, " of sweep ", sweep,
                                              " has a result but is not listed as completed"));
    }
    trial.options = std::move(options->second);
  }
  return absl::OkStatus();
}

absl::StatusOr<std::vector<CompletedTrial>> ReadCompletedTrials(
    ResultsReader& reader, const std::vector<std::string>& sweeps) {
  std::vector<CompletedTrial> all;
  for (const std::string& sweep : sweeps) {
    absl::StatusOr<std::vector<CompletedTrial>> trials = reader.CompletedTrials(sweep);
    if (!trials.ok()) {
      return absl::Status(trials.status().code(),
                          absl::StrCat("sweep ", sweep, ": ", trials.status().message()));
    }
    for (CompletedTrial& trial : *trials) {
      trial.sweep = sweep;
      all.push_back(std::move(trial));
    }
  }
  return all;
}

}  // namespace totalgrad::results
