// The work-precision plots of a gradient study (gnuplot data and scripts,
// and PNGs when gnuplot runs), written by `totalgrad study --output-dir`.
#ifndef TOTALGRAD_CLIENT_CORE_COMMANDS_STUDY_PLOTS_H_
#define TOTALGRAD_CLIENT_CORE_COMMANDS_STUDY_PLOTS_H_

#include <string>
#include <vector>

#include "absl/status/statusor.h"
#include "core/study/study.h"
#include "io/study_file.h"

namespace totalgrad::cli {

// Writes the gnuplot data and scripts of the work-precision plot (relative
// RMSE against seconds per gradient, log-log, one panel per horizon, one
// curve per estimator over P, PILCO as a point, the reference's noise floor
// as a dashed line) and of the horizon sweep at spec.sweep_particles (or the
// nearest P of the study), into `dir`. When run_gnuplot, runs gnuplot on the
// scripts to make PNGs and PDFs (each script draws the PNG unless gnuplot
// runs it after `format = 'pdf'`), labelling each point with its P. Returns the files written. Cells that are omitted or
// whose horizon's reference estimators disagree are not drawn (they are
// listed in the table's omissions).
absl::StatusOr<std::vector<std::string>> WriteStudyPlots(const study::StudyResult& result,
                                                         const io::StudySpec& spec,
                                                         const std::string& dir, bool run_gnuplot);

}  // namespace totalgrad::cli

#endif  // TOTALGRAD_CLIENT_CORE_COMMANDS_STUDY_PLOTS_H_
