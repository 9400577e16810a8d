#include "client/service_commands/success_plot.h"

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <map>

#include "absl/strings/str_cat.h"
#include "client/core_commands/gnuplot.h"
#include "client/service_commands/format.h"
#include "results/plot_style.h"

namespace totalgrad::cli {

int ReportPlot(const std::string& command, const std::string& path, const std::string& problem) {
  if (!problem.empty()) {
    std::cerr << "error: results " << command << " --plot: " << problem << "\n";
    return 1;
  }
  std::cerr << "plot written to " << path << "\n";
  return 0;
}

std::string WriteSuccessPlot(const SuccessPlotInput& input, const std::string& path) {
  const std::string extension = std::filesystem::path(path).extension().string();
  if (!IsPlotExtension(extension)) return "--plot: " + PlotExtensionHint();
  if (std::none_of(input.points.begin(), input.points.end(),
                   [](const SuccessPoint& p) { return p.success.trials > 0; })) {
    return "no completed trial yet; nothing to plot";
  }
  std::error_code error;
  const std::string output = std::filesystem::absolute(path, error).lexically_normal().string();
  if (error) return absl::StrCat("--plot: cannot resolve ", path, ": ", error.message());

  // Panels in first-appearance order; every panel shows the same methods in
  // the same places, so a method sits at one x in every panel.
  std::vector<std::string> variants, methods;
  for (const SuccessPoint& p : input.points) {
    if (std::find(variants.begin(), variants.end(), p.variant) == variants.end()) variants.push_back(p.variant);
    if (std::find(methods.begin(), methods.end(), p.method) == methods.end()) methods.push_back(p.method);
  }
  const auto x_of = [&methods](const std::string& method) {
    return static_cast<int>(std::find(methods.begin(), methods.end(), method) - methods.begin());
  };

  // One block per (variant, method): x rate low high successes trials paper.
  const std::string data_path = output + ".dat";
  std::map<std::pair<std::string, std::string>, int> block;
  {
    std::ofstream data(data_path);
    if (!data) return "cannot write " + data_path;
    int index = 0;
    for (const std::string& variant : variants) {
      for (const SuccessPoint& p : input.points) {
        if (p.variant != variant) continue;
        data << "# " << p.method << " | " << variant
             << "\n# x rate wilson95_low wilson95_high successes trials paper_rate\n";
        const auto number = [](double v) { return std::isfinite(v) ? FormatNumber(v) : "NaN"; };
        const results::WilsonRate& s = p.success;
        data << x_of(p.method) << " " << (s.trials > 0 ? number(s.rate) : "NaN") << " "
             << (s.trials > 0 ? number(s.low) : "NaN") << " "
             << (s.trials > 0 ? number(s.high) : "NaN") << " " << s.successes << " " << s.trials
             << " " << number(p.paper_rate) << "\n\n\n";
        block[{variant, p.method}] = index++;
      }
    }
    if (!data) return "cannot write " + data_path;
  }

  const int columns = variants.size() <= 1 ? 1 : 2;
  const int rows = static_cast<int>((variants.size() + columns - 1) / columns);
  const int width = std::max(520, 70 * static_cast<int>(methods.size()) + 160) * columns;
  const int height = 380 * rows + 40;
  const std::string script_path = output + ".gp";
  {
    std::ofstream script(script_path);
    if (!script) return "cannot write " + script_path;
    script << "# " << input.title << ": redraw with `gnuplot " << script_path << "`\n"
           << GnuplotTerminal(extension, width, height) << "set output " << GnuplotQuote(output)
           << "\n"
           << "set grid ytics\nset ylabel \"success rate (95% Wilson interval)\"\n"
           << "set yrange [0:1.15]\nset ytics 0,0.2,1\nset xrange [-0.6:"
           << static_cast<double>(methods.size()) - 0.4 << "]\n"
           << "set key outside right top vertical font \",9\" samplen 1\n"
           << "set bars small\nset xtics (";
    for (size_t m = 0; m < methods.size(); ++m) {
      script << (m == 0 ? "" : ", ") << GnuplotQuote(methods[m]) << " " << m;
    }
    script << ")\nset multiplot layout " << rows << "," << columns << " title "
           << GnuplotQuote(input.title) << "\n";
    for (const std::string& variant : variants) {
      const auto title = std::find(input.panel_variants.begin(), input.panel_variants.end(), variant);
      const std::string panel_title =
          title != input.panel_variants.end() &&
                  static_cast<size_t>(title - input.panel_variants.begin()) < input.panel_titles.size()
              ? input.panel_titles[title - input.panel_variants.begin()]
              : (variant.empty() ? std::string("all trials") : variant);
      script << "set title " << GnuplotQuote(panel_title) << "\nplot ";
      bool first = true, paper_titled = false;
      for (const SuccessPoint& p : input.points) {
        if (p.variant != variant) continue;
        const std::string source = GnuplotQuote(data_path) + " index " +
                                   std::to_string(block[{variant, p.method}]);
        const std::string colour = "lc rgb " + GnuplotQuote(results::MethodColour(p.method));
        script << (first ? "" : ", \\\n     ") << source
               << " using 1:2:3:4 with yerrorbars " << colour << " pt 7 ps 1.1 lw 2 title "
               << GnuplotQuote(p.method) << ", \\\n     " << source
               << " using 1:(1.06):(sprintf(\"%d/%d\", $5, $6)) with labels font \",8\" notitle";
        if (std::isfinite(p.paper_rate)) {
          script << ", \\\n     " << source
                 << " using 1:7 with points pt 12 ps 1.6 lw 1.5 lc rgb \"black\" "
                 << (paper_titled ? "notitle" : "title \"paper\"");
          paper_titled = true;
        }
        first = false;
      }
      script << "\n";
    }
    script << "unset multiplot\n";
    if (!script) return "cannot write " + script_path;
  }
  return RunGnuplot(script_path);
}

}  // namespace totalgrad::cli
