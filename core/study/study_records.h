// The study's records (issue 13): a cell of the error-vs-time table and the
// reference gradient of one horizon, with their field tables
// (core/common/record.h): the one place that lists a cell's and a reference
// gradient's fields. The order is the CSV's column order (table.csv,
// references.csv; docs/error-vs-time.md), then the JSON-only fields. Every
// writer and reader of these records (results.json, the CSVs, the tables,
// the service's proto and SQLite rows, the worker's study rows) goes through
// the tables. Adding a field: docs/core.md, "Records, and adding a field".
//
// Header only (the tables too), as core/learner/episode_record.h: the
// worker's runtime, which links no numerical code, converts study rows to
// the wire with them.
#ifndef TOTALGRAD_CORE_STUDY_STUDY_RECORDS_H_
#define TOTALGRAD_CORE_STUDY_STUDY_RECORDS_H_

#include <limits>
#include <string>
#include <vector>

#include "absl/strings/str_join.h"
#include "core/common/record.h"
#include "core/common/types.h"

namespace totalgrad::study {

struct ReferenceGradient {
  int horizon = 0;
  Vector gradient;                 // g*
  Vector standard_error;           // per coordinate
  double norm = 0;                 // |g*|
  double relative_error = 0;       // |SE| / |g*|
  double floor = 0;                // 1.96 |SE| / |g*|, the plots' noise floor
  double objective = 0;            // J at this horizon (mean over the reference runs)
  std::vector<std::string> used;   // labels of the estimators pooled
  std::vector<int> replicates;     // per used estimator
  double agreement_max_z = 0;      // between the first two used estimators
  double agreement_mean_z2 = 0;
  // The power of that check: 1.96 |sqrt(SE_a^2 + SE_b^2)| / |g*|, about the
  // relative difference between the two estimators' means that would still
  // pass. Above 1 a difference as large as g* itself passes: the check has
  // no power (one estimator's SE dwarfs the other's, e.g. RP where its
  // pathwise gradients explode), "agree" says nothing, and g* rests on the
  // more precise estimator; the note says so. NaN: not computed (fewer than
  // two estimators, |g*| = 0, or results written before it existed).
  double agreement_resolution = std::numeric_limits<double>::quiet_NaN();
  bool agree = true;               // false also when fewer than two could be used
  std::string note;                // what was left out and why
  double seconds = 0;
};

struct CellResult {
  static constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
  std::string estimator;   // label
  std::string method;      // estimators::MethodName of the spec's method
  int particles = 0;       // 0 for PILCO
  int horizon = 0;
  int replicates = 0;      // finite estimates the statistics use
  int nonfinite = 0;       // estimates flagged finite = false (excluded)
  int errors = 0;          // Estimate returned an error
  std::string error;       // the first error message
  bool budget_hit = false; // stopped early by cell_budget_seconds
  bool omitted = false;    // no statistics (omission_reason says why)
  std::string omission_reason;
  double time_min_s = kNaN;
  double time_median_s = kNaN;
  double rel_rmse = kNaN;
  double rel_bias = kNaN;
  double rel_bias_noise = kNaN;
  double total_variance = kNaN;
  double cos_mean = kNaN;
  double objective_mean = kNaN;  // the estimates' J (PILCO: its moment-matched J)
  double ess_mean = kNaN;
  double ess_min = kNaN;
  double k_lr_mean = kNaN;
  std::vector<double> k_lr_per_step;  // H entries when the method reports k_LR
  bool reference_agrees = true;       // copied from the horizon's reference
  double reference_floor = kNaN;      // the horizon's reference floor (1.96 |SE| / |g*|)
};

// The cell's note for tables: the omission, the budget, a disagreeing
// reference and the first error, "; "-separated ("" when there is nothing to
// say). A function of the cell's other fields, so it is a derived field of
// the cell's record.
inline std::string CellNote(const CellResult& c) {
  std::vector<std::string> notes;
  if (c.omitted) notes.push_back("omitted: " + c.omission_reason);
  else if (!c.omission_reason.empty()) notes.push_back(c.omission_reason);
  if (c.budget_hit) notes.push_back("budget");
  if (!c.reference_agrees) notes.push_back("reference disagrees");
  if (!c.error.empty() && !c.omitted) notes.push_back(c.error);
  return notes.empty() ? "" : absl::StrJoin(notes, "; ");
}

inline const record::FieldTable<CellResult>& CellFields() {
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

inline const record::FieldTable<ReferenceGradient>& ReferenceFields() {
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

#endif  // TOTALGRAD_CORE_STUDY_STUDY_RECORDS_H_
