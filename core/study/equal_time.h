// Which estimator gives the most accurate gradient for a given run time: a
// study's work-precision curves (core/study/study.h) read at fixed seconds
// per gradient (docs/error-vs-time.md, summary tables).
//
// For one estimator and horizon the measured points are its cells in order
// of particle count P: (time_min_s, rel_rmse). The error at T seconds is
// interpolated linearly in (log time, log error) between two consecutive
// measured P whose times bracket T; "not available" (NaN) when no such pair
// exists (T outside the measured range, or next to a cell that could not be
// measured: omitted, non-finite, no time). When timing noise makes the time
// fall with P somewhere, several pairs may bracket T; the lowest error is
// taken (a user could run that P). PILCO (particles = 0: one deterministic
// point) has no curve; its time and error are reported beside the table.
//
// At each (horizon, T) the winner is the estimator with the lowest
// interpolated error, and every other estimator's error is given as a ratio
// to it. Where the horizon's reference estimators disagree there is no
// winner and no ratio (the errors are against a reference that is itself
// in doubt). Where the winner's error is below the reference's noise floor
// the ratios to it cannot be resolved; the row says so.
//
// "n/a outside the measured range" can hide a better answer: an estimator
// whose largest P finished in less than T seconds with a lower error than
// the winner's (or than anything, where no curve reaches T) was measured to
// do better within T. Each row therefore also names the lowest error
// measured in at most T seconds by an estimator other than the winner (any
// P), when it is below the winner's or there is no winner; a user with T
// seconds can run that cell.
//
// Thread safety: pure functions.
#ifndef TOTALGRAD_CORE_STUDY_EQUAL_TIME_H_
#define TOTALGRAD_CORE_STUDY_EQUAL_TIME_H_

#include <string>
#include <utility>
#include <vector>

#include "core/study/study.h"

namespace totalgrad::study {

// One measured point of a work-precision curve; NaN marks a cell that could
// not be measured (the curve is broken there).
struct TimeErrorPoint {
  double seconds = CellResult::kNaN;
  double error = CellResult::kNaN;
};

// The error at `seconds` (> 0) on the curve through `points` (in P order),
// as described above; NaN when not available.
double InterpolateErrorAtTime(const std::vector<TimeErrorPoint>& points, double seconds);

struct EqualTimeRow {
  int horizon = 0;
  double seconds = 0;                // T, seconds per gradient
  bool reference_agrees = true;
  // False where the agreement check had no power (ReferenceGradient::
  // agreement_resolution > 1): g* rests on one estimator; the winner is
  // still named, marked. True where the resolution is unknown (NaN).
  bool reference_checked = true;
  double floor = CellResult::kNaN;   // the reference's 1.96 |SE| / |g*|
  std::string winner;                // empty: no winner (disagreement, or none measured at T)
  double winner_error = CellResult::kNaN;
  bool winner_below_floor = false;
  // Every particle estimator of the study, in study order, with its
  // interpolated error (NaN: n/a) and its ratio to the winner's (NaN when
  // there is no winner or the error is n/a).
  std::vector<std::string> estimators;
  std::vector<double> errors;
  std::vector<double> ratios;
  // The lowest error of a measured particle cell of another estimator than
  // the winner with time <= T, when it is below winner_error or there is no
  // winner (and the references agree); otherwise best_within is empty.
  std::string best_within;
  int best_within_particles = 0;
  double best_within_error = CellResult::kNaN;
  double best_within_seconds = CellResult::kNaN;
};

// PILCO's (or any particle-free estimator's) single point per horizon.
struct FixedCostPoint {
  std::string estimator;
  int horizon = 0;
  double seconds = CellResult::kNaN;
  double error = CellResult::kNaN;
  std::string omission_reason;  // the cell's, when it was omitted (e.g. PILCO with two angles)
};

struct EqualTimeComparison {
  std::vector<EqualTimeRow> rows;          // horizon-major (study order), then seconds
  std::vector<FixedCostPoint> fixed_cost;  // particles = 0 cells, horizon order
};

// The comparison of `result` at each of `seconds` (each > 0).
EqualTimeComparison CompareAtEqualTime(const StudyResult& result, const std::vector<double>& seconds);

}  // namespace totalgrad::study

#endif  // TOTALGRAD_CORE_STUDY_EQUAL_TIME_H_
