#include "results/completed_trial.h"

#include "absl/status/status.h"
#include "absl/strings/str_cat.h"

namespace totalgrad::results {

const record::FieldTable<CompletedTrial>& CompletedTrialFields() {
  using T = CompletedTrial;
  static const record::FieldTable<T> table = {
      {"sweep", &T::sweep},
      {"job_id", &T::job_id},
      {"method", &T::method},
      {"seed", &T::seed},
      {"variant", &T::variant},
      {"attempt", &T::attempt},
      {"success", &T::success},
      {"final_eval_cost", &T::final_eval_cost},
      {"episodes", &T::episodes},
      {"held_fraction", &T::held_fraction},
      {"options", &T::options},
  };
  return table;
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
