#include "client/service_commands/curves_plot.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <set>

#include "absl/strings/str_cat.h"
#include "client/service_commands/connection.h"
#include "client/service_commands/format.h"

namespace totalgrad::cli {

using results::CurvePanel;
using results::CurvePoint;
using results::DescribePanel;
using results::MethodColour;

namespace {

std::string Quote(const std::string& text) {
  std::string out = "\"";
  for (char c : text) {
    if (c == '"' || c == '\\') out += '\\';
    out += c;
  }
  return out + "\"";
}

// Panels per row: 1, 2 up to four panels, then 3.
int Columns(size_t panels) { return panels <= 1 ? 1 : panels <= 4 ? 2 : 3; }

}  // namespace

std::string WriteCurvesPlot(const CurvesPlotInput& input, const std::string& path) {
  const std::string extension = std::filesystem::path(path).extension().string();
  if (extension != ".svg" && extension != ".png") {
    return "--plot: the file must end in .svg or .png";
  }
  if (input.curves.empty()) return "no curve has a point yet; nothing to plot";
  std::error_code error;
  const std::string output = std::filesystem::absolute(path, error).lexically_normal().string();
  if (error) return absl::StrCat("--plot: cannot resolve ", path, ": ", error.message());

  // Variants and, per variant, methods in first-appearance order.
  std::vector<std::string> variants;
  std::map<std::string, std::vector<std::string>> methods;
  std::map<std::pair<std::string, std::string>, std::vector<const CurvePoint*>> points;
  int last_episode = 0;
  for (const CurvePoint& p : input.curves) {
    if (!methods.count(p.variant)) variants.push_back(p.variant);
    auto& list = methods[p.variant];
    if (std::find(list.begin(), list.end(), p.method) == list.end()) list.push_back(p.method);
    points[{p.variant, p.method}].push_back(&p);
    last_episode = std::max(last_episode, p.episode);
  }
  std::map<std::string, CurvePanel> panel_of;
  for (const CurvePanel& panel : input.panels) panel_of.emplace(panel.variant, panel);

  const std::string data_path = output + ".dat";
  std::map<std::pair<std::string, std::string>, int> block;  // gnuplot "index"
  {
    std::ofstream data(data_path);
    if (!data) return "cannot write " + data_path;
    int index = 0;
    for (const std::string& variant : variants) {
      for (const std::string& method : methods[variant]) {
        data << "# " << method << " | " << variant << "\n# episode q25 median q75 trials\n";
        for (const CurvePoint* p : points[{variant, method}]) {
          data << p->episode << " " << FormatNumber(p->q25) << " " << FormatNumber(p->median)
               << " " << FormatNumber(p->q75) << " " << p->trials << "\n";
        }
        data << "\n\n";
        block[{variant, method}] = index++;
      }
    }
    if (!data) return "cannot write " + data_path;
  }

  const int columns = Columns(variants.size());
  const int rows = static_cast<int>((variants.size() + columns - 1) / columns);
  const int width = 760 * columns, height = 440 * rows + 40;
  const std::string script_path = output + ".gp";
  {
    std::ofstream script(script_path);
    if (!script) return "cannot write " + script_path;
    script << "# " << input.sweep_name << ": redraw with `gnuplot " << script_path << "`\n";
    if (extension == ".svg") {
      script << "set terminal svg size " << width << "," << height << " dynamic font \"sans,11\"\n";
    } else {
      script << "set terminal pngcairo size " << width << "," << height << " font \"sans,10\"\n";
    }
    script << "set output " << Quote(output) << "\n"
           << "set termoption noenhanced\n"  // option names hold underscores
           << "set style fill transparent solid 0.18 noborder\n"
           << "set grid\nset xlabel \"episode\"\nset ylabel \"evaluation cost\"\n"
           << (last_episode <= 20 ? "set xtics 1\n" : "")
           // Beside the plot, not in a corner of it: costs start high on the
           // left and fall, so any inside corner hides some curve.
           << "set key outside right top vertical box font \",9\" samplen 2 spacing 0.9\n"
           << "set multiplot layout " << rows << "," << columns << " title "
           << Quote("sweep " + input.sweep_name +
                    ": evaluation cost per episode, median and quartiles over trials "
                    "(n = trials)")
           << "\n";
    for (const std::string& variant : variants) {
      auto found = panel_of.find(variant);
      const CurvePanel panel =
          found != panel_of.end() ? found->second : DescribePanel(variant, {});
      script << "set title " << Quote(panel.title) << "\nplot ";
      bool first = true;
      for (const std::string& method : methods[variant]) {
        int trials = 0;
        for (const CurvePoint* p : points[{variant, method}]) trials = std::max(trials, p->trials);
        const std::string colour = "lc rgb " + Quote(MethodColour(method));
        const int index = block[{variant, method}];
        script << (first ? "" : ", \\\n     ") << Quote(data_path) << " index " << index
               << " using 1:2:4 with filledcurves " << colour << " notitle, \\\n     "
               << Quote(data_path) << " index " << index << " using 1:3 with linespoints "
               << colour << " lw 2 pt 7 ps 0.5 title "
               << Quote(absl::StrCat(method, " (n=", trials, ")"));
        first = false;
      }
      if (std::isfinite(panel.threshold)) {
        script << ", \\\n     " << FormatNumber(panel.threshold)
               << " with lines dt 2 lw 1.5 lc rgb \"#555555\" title "
               << Quote("success threshold " + FormatNumber(panel.threshold));
      }
      script << "\n";
    }
    script << "unset multiplot\n";
    if (!script) return "cannot write " + script_path;
  }
  const std::string command = "gnuplot " + Quote(script_path) + " 2>&1";
  FILE* pipe = popen(command.c_str(), "r");
  if (pipe == nullptr) return "cannot run gnuplot (install gnuplot-nox)";
  std::string messages;
  char buffer[256];
  while (fgets(buffer, sizeof(buffer), pipe) != nullptr) messages += buffer;
  const int rc = pclose(pipe);
  if (rc != 0) return "gnuplot failed (is gnuplot-nox installed?): " + messages;
  return "";
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
