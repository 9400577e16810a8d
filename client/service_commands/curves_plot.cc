#include "client/service_commands/curves_plot.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <set>

#include "absl/strings/str_cat.h"
#include "client/core_commands/gnuplot.h"
#include "client/service_commands/connection.h"
#include "client/service_commands/format.h"

namespace totalgrad::cli {

using results::CurvePanel;
using results::CurvePoint;
using results::DescribePanel;
using results::MethodColour;

namespace {

// Panels per row: 1, 2 up to four panels, then 3.
int Columns(size_t panels) { return panels <= 1 ? 1 : panels <= 4 ? 2 : 3; }

using Key = std::pair<std::string, std::string>;  // (variant, method)

// The data file: one block (gnuplot "index") per (variant, method) of all
// runs, then with top > 0 one per (variant, method) of the best runs, each
// row "episode q25 median q75 trials mean standard_error". Returns "" or
// what went wrong.
std::string WriteCurveBlocks(const std::string& data_path, const std::vector<std::string>& variants,
                             std::map<std::string, std::vector<std::string>>& methods,
                             std::map<Key, std::vector<const CurvePoint*>>& points,
                             std::map<Key, std::vector<const CurvePoint*>>& best_points, int top,
                             std::map<Key, int>* block, std::map<Key, int>* best_block) {
  std::ofstream data(data_path);
  if (!data) return "cannot write " + data_path;
  int index = 0;
  const auto write = [&](const std::string& what, const std::vector<const CurvePoint*>& rows,
                         const std::string& method, const std::string& variant) {
    data << "# " << method << " | " << variant << what
         << "\n# episode q25 median q75 trials mean standard_error\n";
    for (const CurvePoint* p : rows) {
      const results::SampleSummary& v = p->values;
      data << p->episode << " " << FormatNumber(v.q25) << " " << FormatNumber(v.median) << " "
           << FormatNumber(v.q75) << " " << v.trials << " " << FormatNumber(v.mean) << " "
           << (std::isnan(v.standard_error) ? std::string("0") : FormatNumber(v.standard_error))
           << "\n";
    }
    if (rows.empty()) data << "NaN NaN NaN NaN 0 NaN NaN\n";
    data << "\n\n";
    return index++;
  };
  for (const std::string& variant : variants) {
    for (const std::string& method : methods[variant]) {
      (*block)[{variant, method}] = write("", points[{variant, method}], method, variant);
    }
  }
  if (top > 0) {
    for (const std::string& variant : variants) {
      for (const std::string& method : methods[variant]) {
        (*best_block)[{variant, method}] = write(absl::StrCat(" | the ", top, " best runs"),
                                                 best_points[{variant, method}], method, variant);
      }
    }
  }
  if (!data) return "cannot write " + data_path;
  return "";
}

}  // namespace

std::string WriteCurvesPlot(const CurvesPlotInput& input, const std::string& path) {
  const std::string extension = std::filesystem::path(path).extension().string();
  if (!IsPlotExtension(extension)) return "--plot: " + PlotExtensionHint();
  if (input.curves.empty()) return "no curve has a point yet; nothing to plot";
  std::error_code error;
  const std::string output = std::filesystem::absolute(path, error).lexically_normal().string();
  if (error) return absl::StrCat("--plot: cannot resolve ", path, ": ", error.message());

  // Variants and, per variant, methods in first-appearance order.
  std::vector<std::string> variants;
  std::map<std::string, std::vector<std::string>> methods;
  std::map<Key, std::vector<const CurvePoint*>> points, best_points;
  int last_episode = 0;
  for (const CurvePoint& p : input.curves) {
    if (!methods.count(p.variant)) variants.push_back(p.variant);
    auto& list = methods[p.variant];
    if (std::find(list.begin(), list.end(), p.method) == list.end()) list.push_back(p.method);
    points[{p.variant, p.method}].push_back(&p);
    last_episode = std::max(last_episode, p.episode);
  }
  const bool figure3 = input.top > 0;
  for (const CurvePoint& p : input.best_curves) best_points[{p.variant, p.method}].push_back(&p);
  std::map<std::string, CurvePanel> panel_of;
  for (const CurvePanel& panel : input.panels) panel_of.emplace(panel.variant, panel);

  const std::string data_path = output + ".dat";
  std::map<Key, int> block, best_block;
  const std::string problem = WriteCurveBlocks(data_path, variants, methods, points, best_points,
                                               input.top, &block, &best_block);
  if (!problem.empty()) return problem;

  // Figure 3: a row of three panels per variant; else the variants in a grid.
  const int columns = figure3 ? 3 : Columns(variants.size());
  const int rows = figure3 ? static_cast<int>(variants.size())
                           : static_cast<int>((variants.size() + columns - 1) / columns);
  const int width = (figure3 ? 620 : 760) * columns, height = (figure3 ? 380 : 440) * rows + 40;
  const std::string script_path = output + ".gp";
  {
    std::ofstream script(script_path);
    if (!script) return "cannot write " + script_path;
    script << "# " << input.sweep_name << ": redraw with `gnuplot " << script_path << "`\n"
           << GnuplotTerminal(extension, width, height) << "set output " << GnuplotQuote(output) << "\n"
           << "set style fill transparent solid 0.18 noborder\n"
           << "set grid\nset xlabel \"episode\"\nset ylabel \"evaluation cost\"\n"
           << (last_episode <= 20 ? "set xtics 1\n" : "")
           // Beside the plot, not in a corner of it: costs start high on the
           // left and fall, so any inside corner hides some curve.
           << "set key outside right top vertical box font \",9\" samplen 2 spacing 0.9\n"
           << "set multiplot layout " << rows << "," << columns << " title "
           << GnuplotQuote(figure3 ? absl::StrCat("sweep ", input.sweep_name,
                                                  ": evaluation cost per episode (the paper's "
                                                  "Figure 3): all runs, median and quartiles; all "
                                                  "runs, mean +- standard error; the ",
                                                  input.top, " best runs by final cost")
                                   : "sweep " + input.sweep_name +
                                         ": evaluation cost per episode, median and quartiles "
                                         "over trials (n = trials)")
           << "\n";
    // One panel: per method a band (columns low:high) and a line (column y)
    // of block `index_of`, n from `trials_of`.
    const auto panel = [&](const std::string& title, const std::string& variant,
                           const std::map<Key, int>& index_of,
                           const std::map<Key, std::vector<const CurvePoint*>>& rows_of,
                           const std::string& band, const std::string& line, double threshold) {
      script << "set title " << GnuplotQuote(title) << "\nplot ";
      bool first = true;
      for (const std::string& method : methods[variant]) {
        int trials = 0;
        const auto rows_found = rows_of.find({variant, method});
        if (rows_found != rows_of.end()) {
          for (const CurvePoint* p : rows_found->second) trials = std::max(trials, p->values.trials);
        }
        const std::string colour = "lc rgb " + GnuplotQuote(MethodColour(method));
        const std::string source = GnuplotQuote(data_path) + " index " +
                                   std::to_string(index_of.at({variant, method}));
        script << (first ? "" : ", \\\n     ") << source << " using " << band
               << " with filledcurves " << colour << " notitle, \\\n     " << source << " using "
               << line << " with linespoints " << colour << " lw 2 pt 7 ps 0.5 title "
               << GnuplotQuote(absl::StrCat(method, " (n=", trials, ")"));
        first = false;
      }
      if (std::isfinite(threshold)) {
        script << ", \\\n     " << FormatNumber(threshold)
               << " with lines dt 2 lw 1.5 lc rgb \"#555555\" title "
               << GnuplotQuote("success threshold " + FormatNumber(threshold));
      }
      script << "\n";
    };
    for (const std::string& variant : variants) {
      auto found = panel_of.find(variant);
      const CurvePanel described =
          found != panel_of.end() ? found->second : DescribePanel(variant, {});
      if (!figure3) {
        panel(described.title, variant, block, points, "1:2:4", "1:3", described.threshold);
        continue;
      }
      panel(described.title + ": all runs, median and quartiles", variant, block, points, "1:2:4",
            "1:3", described.threshold);
      panel(described.title + ": all runs, mean +- standard error", variant, block, points,
            "1:($6-$7):($6+$7)", "1:6", described.threshold);
      panel(absl::StrCat(described.title, ": the ", input.top, " best runs, median and quartiles"),
            variant, best_block, best_points, "1:2:4", "1:3", described.threshold);
    }
    script << "unset multiplot\n";
    if (!script) return "cannot write " + script_path;
  }
  return RunGnuplot(script_path);
}

std::string FetchCurvePanels(Connection* connection, const std::string& sweep_name,
                             std::vector<CurvePanel>* panels) {
  v1::ListJobsRequest request;
  request.set_sweep_name(sweep_name);
  request.set_page_size(1000);
  std::set<std::string> seen;
  while (true) {
    v1::ListJobsResponse response;
    const grpc::Status status =
        connection->Call(&v1::ControlService::Stub::ListJobs, request, &response);
    if (!status.ok()) return status.error_message();
    for (const v1::JobInfo& job : response.jobs()) {
      if (job.kind() == v1::JOB_KIND_STUDY || !seen.insert(job.variant()).second) continue;
      std::vector<std::pair<std::string, std::string>> options;
      for (const auto& option : job.options()) options.emplace_back(option.key(), option.value());
      panels->push_back(DescribePanel(job.variant(), options));
    }
    if (response.next_after_job_id() == 0) break;
    request.set_after_job_id(response.next_after_job_id());
  }
  return "";
}

}  // namespace totalgrad::cli
