// `totalgrad study FILE`: a gradient study (core/study/study.h) described by a
// JSON file, printed as a table (text, CSV or JSON) and, with --output-dir,
// written there with log-log work-precision plots (gnuplot, PNG).
//
// The study file format and its parser: io/study_file.h.
//
// The formatting and plotting are exposed for in-process tests.
#ifndef TOTALGRAD_CLIENT_CORE_COMMANDS_STUDY_COMMAND_H_
#define TOTALGRAD_CLIENT_CORE_COMMANDS_STUDY_COMMAND_H_

#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "absl/status/statusor.h"
#include "core/study/study.h"
#include "io/study_file.h"

namespace totalgrad::cli {

// The result as a fixed-width table (references, cells, omissions), as CSV
// (one row per cell, header first) and as JSON (NaN as null).
std::string StudyTableText(const study::StudyResult& result);
std::string StudyTableCsv(const study::StudyResult& result);
std::string StudyReferenceCsv(const study::StudyResult& result);
nlohmann::ordered_json StudyToJson(const study::StudyResult& result, const io::StudySpec& spec);

// Writes the gnuplot data and scripts of the work-precision plot (relative
// RMSE against seconds per gradient, log-log, one panel per horizon, one
// curve per estimator over P, PILCO as a point, the reference's noise floor
// as a dashed line) and of the horizon sweep at spec.sweep_particles (or the
// nearest P of the study), into `dir`. When run_gnuplot, runs gnuplot on the
// scripts to make PNGs. Returns the files written. Cells that are omitted or
// whose horizon's reference estimators disagree are not drawn (they are
// listed in the table's omissions).
absl::StatusOr<std::vector<std::string>> WriteStudyPlots(const study::StudyResult& result,
                                                         const io::StudySpec& spec,
                                                         const std::string& dir, bool run_gnuplot);

}  // namespace totalgrad::cli

#endif  // TOTALGRAD_CLIENT_CORE_COMMANDS_STUDY_COMMAND_H_
