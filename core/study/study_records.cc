// The study's record tables (core/common/record.h): the one place that lists
// a cell's and a reference gradient's fields. The order is the CSV's column
// order (table.csv, references.csv; docs/error-vs-time.md), then the
// JSON-only fields. Adding a field: docs/core.md, "Records, and adding a
// field".
#include <vector>

#include "absl/strings/str_join.h"
#include "core/study/study.h"

namespace totalgrad::study {

std::string CellNote(const CellResult& c) {
  std::vector<std::string> notes;
  if (c.omitted) notes.push_back("omitted: " + c.omission_reason);
  else if (!c.omission_reason.empty()) notes.push_back(c.omission_reason);
  if (c.budget_hit) notes.push_back("budget");
  if (!c.reference_agrees) notes.push_back("reference disagrees");
  if (!c.error.empty() && !c.omitted) notes.push_back(c.error);
  return notes.empty() ? "" : absl::StrJoin(notes, "; ");
}

const record::FieldTable<CellResult>& CellFields() {
  using C = CellResult;
  static const record::FieldTable<C>* const table = new record::FieldTable<C>{
      {"estimator", &C::estimator},
      {"method", &C::method},
      {"particles", &C::particles},
      {"horizon", &C::horizon},
      {"replicates", &C::replicates},
      {"nonfinite", &C::nonfinite},
      {"errors", &C::errors},
      {"time_min_s", &C::time_min_s},
      {"time_median_s", &C::time_median_s},
      {"rel_rmse", &C::rel_rmse},
      {"rel_bias", &C::rel_bias},
      {"rel_bias_noise", &C::rel_bias_noise},
      {"total_variance", &C::total_variance},
      {"cos_mean", &C::cos_mean},
      {"objective_mean", &C::objective_mean},
      {"ess_mean", &C::ess_mean},
      {"ess_min", &C::ess_min},
      {"k_lr_mean", &C::k_lr_mean},
      {"reference_agrees", &C::reference_agrees},
      {"reference_floor", &C::reference_floor},
      {"budget_hit", &C::budget_hit},
      {"omitted", &C::omitted},
      {"note", &CellNote},
      // JSON, proto and SQL only: the note above already says them in a
      // spreadsheet's terms, and a per-step list is no CSV cell.
      {"error", &C::error, /*csv=*/false},
      {"omission_reason", &C::omission_reason, /*csv=*/false},
      {"k_lr_per_step", &C::k_lr_per_step, /*csv=*/false},
  };
  return *table;
}

const record::FieldTable<ReferenceGradient>& ReferenceFields() {
  using G = ReferenceGradient;
  static const record::FieldTable<G>* const table = new record::FieldTable<G>{
      {"horizon", &G::horizon},
      {"norm", &G::norm},
      {"relative_error", &G::relative_error},
      {"floor", &G::floor},
      {"objective", &G::objective},
      {"used", &G::used},
      {"replicates", &G::replicates},
      {"agreement_max_z", &G::agreement_max_z},
      {"agreement_mean_z2", &G::agreement_mean_z2},
      {"agreement_resolution", &G::agreement_resolution},
      {"agree", &G::agree},
      {"seconds", &G::seconds},
      {"note", &G::note},
      {"gradient", &G::gradient, /*csv=*/false},
      {"standard_error", &G::standard_error, /*csv=*/false},
  };
  return *table;
}

}  // namespace totalgrad::study
