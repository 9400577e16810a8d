// The success-rate picture of `totalgrad results table SWEEP --plot FILE` and
// `results table1 SWEEPS --plot FILE`: one panel per task variant, each
// method a point at its success rate with its 95% Wilson interval as a bar,
// in the method's fixed colour (results/plot_style.h), "successes/trials"
// above it, and the paper's rate as an open black diamond where Table 1 has
// one. SVG, PDF or PNG by gnuplot, from a data file and a script written
// beside FILE that name files by absolute path (`gnuplot FILE.gp` redraws).
#ifndef TOTALGRAD_CLIENT_SERVICE_COMMANDS_SUCCESS_PLOT_H_
#define TOTALGRAD_CLIENT_SERVICE_COMMANDS_SUCCESS_PLOT_H_

#include <limits>
#include <string>
#include <vector>

#include "results/stats.h"

namespace totalgrad::cli {

// One point: a method's success rate on one task variant.
struct SuccessPoint {
  std::string variant;      // the panel
  std::string method;
  results::WilsonRate success;  // no trial: drawn as "0/0" without a point
  double paper_rate = std::numeric_limits<double>::quiet_NaN();  // NaN: no marker
};

struct SuccessPlotInput {
  std::string title;                      // the picture's heading
  std::vector<SuccessPoint> points;       // panels in first-appearance order
  // Panel titles by variant, in the order of `panel_variants` (a variant
  // without one is titled by itself).
  std::vector<std::string> panel_variants;
  std::vector<std::string> panel_titles;
};

// What every `--plot` of `results` says once its picture is written or not:
// "plot written to PATH" on stderr and 0, or "error: results COMMAND --plot:
// PROBLEM" and 1 (`problem` "" means written).
int ReportPlot(const std::string& command, const std::string& path, const std::string& problem);

// Writes `path` (.svg, .pdf or .png), `path`.dat and `path`.gp and runs
// gnuplot. Returns "" on success, else what went wrong (the file type,
// an unwritable file, gnuplot, no point with a trial).
std::string WriteSuccessPlot(const SuccessPlotInput& input, const std::string& path);

}  // namespace totalgrad::cli

#endif  // TOTALGRAD_CLIENT_SERVICE_COMMANDS_SUCCESS_PLOT_H_
