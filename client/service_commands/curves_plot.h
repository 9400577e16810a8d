// The picture of `totalgrad results curves --plot FILE`: one panel per task
// variant (scene, cost, noise level and any other swept key), each method a
// median curve over its quartile band in the method's fixed colour
// (results/plot_style.h), the success threshold as a dashed line, and n (trials)
// beside each method in the panel's legend. Drawn by gnuplot from a data
// file and a script written beside FILE; both name files by absolute path,
// so `gnuplot FILE.gp` redraws it from any directory.
#ifndef TOTALGRAD_CLIENT_SERVICE_COMMANDS_CURVES_PLOT_H_
#define TOTALGRAD_CLIENT_SERVICE_COMMANDS_CURVES_PLOT_H_

#include <string>
#include <vector>

#include "results/plot_style.h"
#include "results/stats.h"

namespace totalgrad::cli {

class Connection;

struct CurvesPlotInput {
  std::string sweep_name;
  std::vector<results::CurvePoint> curves;  // as from results::Curves()
  // The panels' titles and thresholds by variant; a variant of `curves`
  // without one gets results::DescribePanel(variant, {}) (its name, no threshold).
  std::vector<results::CurvePanel> panels;
  // The paper's Figure 3 when top > 0: per variant a row of three panels,
  // all runs' median and quartiles, all runs' mean +- standard error, and
  // `best_curves` (results::Curves of results::BestRuns(values, top)).
  int top = 0;
  std::vector<results::CurvePoint> best_curves;
};

// Writes `path` (.svg, .pdf or .png), `path`.dat and `path`.gp and runs gnuplot on
// the script. Returns "" on success, else what went wrong (bad extension,
// unwritable file, gnuplot missing or failing, nothing to plot).
std::string WriteCurvesPlot(const CurvesPlotInput& input, const std::string& path);

// The panels of a sweep's variants, from the options of one job of each
// (ListJobs). Returns "" or the error, as text for the caller to print.
std::string FetchCurvePanels(Connection* connection, const std::string& sweep_name,
                             std::vector<results::CurvePanel>* panels);

}  // namespace totalgrad::cli

#endif  // TOTALGRAD_CLIENT_SERVICE_COMMANDS_CURVES_PLOT_H_
