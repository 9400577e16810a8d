#include "client/core_commands/study_plots.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <map>
#include <sstream>

#include "absl/strings/str_cat.h"
#include "client/core_commands/gnuplot.h"
#include "absl/strings/str_format.h"
#include "absl/strings/str_join.h"
#include "client/core_commands/study_format.h"
#include "io/text_file.h"

namespace totalgrad::cli {
namespace {

using io::StudySpec;

bool Plottable(const study::CellResult& c) {
  return !c.omitted && c.reference_agrees && std::isfinite(c.rel_rmse) && c.rel_rmse > 0 &&
         std::isfinite(c.time_min_s) && c.time_min_s > 0;
}

std::string Quote(const std::string& s) {  // gnuplot single-quoted string
  std::string out = "'";
  for (char ch : s) {
    if (ch == '\'') out += "''";
    else out += ch;
  }
  return out + "'";
}


// Twelve gnuplot line styles, one per estimator (modulo 12).
constexpr char kLineStyles[] =
    "set style line 1 lc rgb '#1f77b4' pt 7\nset style line 2 lc rgb '#ff7f0e' pt 5\n"
    "set style line 3 lc rgb '#2ca02c' pt 9\nset style line 4 lc rgb '#d62728' pt 11\n"
    "set style line 5 lc rgb '#9467bd' pt 13\nset style line 6 lc rgb '#8c564b' pt 4\n"
    "set style line 7 lc rgb '#e377c2' pt 6\nset style line 8 lc rgb '#7f7f7f' pt 8\n"
    "set style line 9 lc rgb '#bcbd22' pt 10\nset style line 10 lc rgb '#17becf' pt 12\n"
    "set style line 11 lc rgb '#000000' pt 3\nset style line 12 lc rgb '#aaaa00' pt 1\n";

// A data file of estimator e (wp_<e>.dat, sweep_<e>.dat) as a gnuplot string.
std::string DataFile(const std::string& dir, const std::string& stem, size_t e) {
  return Quote((std::filesystem::path(dir) / absl::StrCat(stem, "_", e, ".dat")).string());
}

// The lines that pick the picture's type: PNG unless gnuplot is run with
// `format = "pdf"` first (RunGnuplots draws both), so `gnuplot NAME.gp`
// alone redraws the PNG.
std::string TerminalChoice(const std::string& dir, const std::string& stem, int width, int height) {
  namespace fs = std::filesystem;
  const std::string base = (fs::path(dir) / stem).string();
  return absl::StrCat("if (!exists('format')) format = 'png'\n", "if (format eq 'pdf') {\n  ",
                      GnuplotTerminal(".pdf", width, height), "  set output ", Quote(base + ".pdf"),
                      "\n} else {\n  ", GnuplotTerminal(".png", width, height), "  set output ",
                      Quote(base + ".png"), "\n}\n");
}

// The estimators in the order of their first cell.
std::vector<std::string> EstimatorLabels(const study::StudyResult& r) {
  std::vector<std::string> labels;
  for (const auto& c : r.cells) {
    if (std::find(labels.begin(), labels.end(), c.estimator) == labels.end()) labels.push_back(c.estimator);
  }
  return labels;
}

// The horizon sweep's P: the requested one, else the study's nearest.
int SweepParticles(const StudySpec& spec) {
  const int sweep_p = spec.sweep_particles;
  int best = -1;
  for (int p : spec.options.particles) {
    if (best < 0 || std::abs(std::log(static_cast<double>(p) / sweep_p)) <
                        std::abs(std::log(static_cast<double>(best) / sweep_p))) {
      best = p;
    }
  }
  return best;
}

// The data files: per estimator wp_<e>.dat and sweep_<e>.dat, and floor.dat.
absl::Status WriteDataFiles(const study::StudyResult& r, const std::vector<int>& horizons,
                            const std::vector<std::string>& labels, int sweep_p,
                            const std::string& dir, std::vector<std::string>& written) {
  namespace fs = std::filesystem;
  // Data: per estimator one file, one block per horizon ("P seconds rmse
  // bias cos"), and one horizon-sweep block ("H rmse cos").
  for (size_t e = 0; e < labels.size(); ++e) {
    std::ostringstream wp, sweep;
    wp << "# " << labels[e] << ": particles seconds_per_gradient rel_rmse rel_bias cos_mean\n";
    for (size_t hi = 0; hi < horizons.size(); ++hi) {
      std::vector<const study::CellResult*> rows;
      for (const auto& c : r.cells) {
        if (c.estimator == labels[e] && c.horizon == horizons[hi] && Plottable(c)) rows.push_back(&c);
      }
      std::sort(rows.begin(), rows.end(),
                [](const auto* a, const auto* b) { return a->particles < b->particles; });
      wp << "# H = " << horizons[hi] << "\n";
      if (rows.empty()) wp << "0 NaN NaN NaN NaN\n";
      for (const auto* c : rows) {
        wp << c->particles << " " << absl::StrFormat("%.6g %.6g %.6g %.6g", c->time_min_s,
                                                     c->rel_rmse, c->rel_bias, c->cos_mean)
           << "\n";
      }
      if (hi + 1 < horizons.size()) wp << "\n\n";
    }
    sweep << "# " << labels[e] << " at P = " << sweep_p << ": horizon rel_rmse cos_mean\n";
    int sweep_rows = 0;
    for (int h : horizons) {
      for (const auto& c : r.cells) {
        if (c.estimator == labels[e] && c.horizon == h && Plottable(c) &&
            (c.particles == sweep_p || c.particles == 0)) {
          sweep << h << " " << absl::StrFormat("%.6g %.6g", c.rel_rmse, c.cos_mean) << "\n";
          ++sweep_rows;
        }
      }
    }
    if (sweep_rows == 0) sweep << "0 NaN NaN\n";
    const std::string wp_path = (fs::path(dir) / absl::StrCat("wp_", e, ".dat")).string();
    const std::string sweep_path = (fs::path(dir) / absl::StrCat("sweep_", e, ".dat")).string();
    if (absl::Status st = io::WriteTextFile(wp_path, wp.str()); !st.ok()) return st;
    if (absl::Status st = io::WriteTextFile(sweep_path, sweep.str()); !st.ok()) return st;
    written.push_back(wp_path);
    written.push_back(sweep_path);
  }
  std::ostringstream floor;
  floor << "# horizon reference_floor (1.96 |SE| / |g*|)\n";
  int floor_rows = 0;
  for (const auto& ref : r.references) {
    if (ref.floor > 0) {
      floor << ref.horizon << " " << absl::StrFormat("%.6g", ref.floor) << "\n";
      ++floor_rows;
    }
  }
  if (floor_rows == 0) floor << "0 NaN\n";
  const std::string path = (fs::path(dir) / "floor.dat").string();
  if (absl::Status st = io::WriteTextFile(path, floor.str()); !st.ok()) return st;
  written.push_back(path);
  return absl::OkStatus();
}

// work_precision.gp: one panel per horizon.
absl::Status WriteWorkPrecisionScript(const study::StudyResult& r, const std::vector<int>& horizons,
                                      const std::vector<std::string>& labels,
                                      const std::string& dir, std::vector<std::string>& written) {
  namespace fs = std::filesystem;
  const int n = static_cast<int>(horizons.size());
  const int cols = n <= 1 ? 1 : 2;
  const int rows = (n + cols - 1) / cols;
  std::ostringstream gp;
  gp << "# Work-precision diagram of a gradient study (totalgrad study).\n"
     << "# Problem: " << r.source << "\n"
     << TerminalChoice(dir, "work_precision", 620 * cols, 470 * rows) << kLineStyles << "set logscale xy\nset format x '%.0e'\nset format y '%g'\n"
     << "set xlabel 'seconds per gradient (min of single-threaded runs)'\n"
     << "set ylabel 'relative RMSE vs reference'\nset grid\nset key outside right top\n"
     << "set multiplot layout " << rows << "," << cols
     << " title '" << (r.scene.empty() ? std::string() : r.scene + ": ")
     << "error against run time, one curve per estimator (labels: P); dashed: reference noise floor'\n";
  for (int hi = 0; hi < n; ++hi) {
    const study::ReferenceGradient* ref = ReferenceFor(r, horizons[hi]);
    gp << "set title 'H = " << horizons[hi] << (ref != nullptr && !ref->agree ? " (reference estimators disagree)" : "")
       << "'\n";
    bool any = false;
    for (const auto& c : r.cells) any = any || (c.horizon == horizons[hi] && Plottable(c));
    if (!any) {
      // Nothing to draw: gnuplot cannot autoscale a log axis on no data.
      gp << "set xrange [1e-4:1]\nset yrange [1e-2:10]\n"
         << "set label 1 'no plottable cells (see the table)' at graph 0.5,0.5 center\n"
         << "plot NaN notitle\nunset label 1\nset autoscale xy\n";
      continue;
    }
    gp << "plot ";
    for (size_t e = 0; e < labels.size(); ++e) {
      gp << DataFile(dir, "wp", e) << " index " << hi << " using 2:3 with linespoints ls "
         << (e % 12) + 1 << " title " << Quote(labels[e]) << ", \\\n     "
         // Each point's P beside it (PILCO's single point has none).
         << DataFile(dir, "wp", e) << " index " << hi
         << " using 2:3:($1 > 0 ? sprintf('%d', $1) : '') with labels offset char 0.9,0.6"
         << " font ',7' tc ls " << (e % 12) + 1 << " notitle, \\\n     ";
    }
    const double floor = ref != nullptr ? ref->floor : 0.0;
    if (floor > 0) {
      gp << absl::StrFormat("%.6g", floor) << " with lines dt 2 lc rgb 'black' title 'floor'\n";
    } else {
      gp << "NaN notitle\n";
    }
  }
  gp << "unset multiplot\n";
  const std::string path = (fs::path(dir) / "work_precision.gp").string();
  if (absl::Status st = io::WriteTextFile(path, gp.str()); !st.ok()) return st;
  written.push_back(path);
  return absl::OkStatus();
}

// horizon_sweep.gp: error and direction against H at fixed P.
absl::Status WriteHorizonSweepScript(const study::StudyResult& r,
                                     const std::vector<std::string>& labels, int sweep_p,
                                     const std::string& dir, std::vector<std::string>& written) {
  namespace fs = std::filesystem;
  std::ostringstream gp;
  gp << "# Horizon sweep at P = " << sweep_p << " (PILCO: its single value per H).\n"
     << "# Problem: " << r.source << "\n"
     << TerminalChoice(dir, "horizon_sweep", 1240, 470) << kLineStyles << "set grid\nset key outside right top\nset xlabel 'horizon H (steps)'\n"
     << "set multiplot layout 1,2 title '" << (r.scene.empty() ? std::string() : r.scene + ": ")
     << "horizon sweep at P = " << sweep_p << "'\n";
  bool any = false;
  for (const auto& c : r.cells) {
    any = any || (Plottable(c) && (c.particles == sweep_p || c.particles == 0));
  }
  if (!any) {
    gp << "set xrange [0:*]\nset yrange [1e-2:10]\n"
       << "set label 1 'no plottable cells (see the table)' at graph 0.5,0.5 center\n";
  }
  gp << "set logscale y\nset ylabel 'relative RMSE vs reference'\nset title 'error'\nplot ";
  for (size_t e = 0; e < labels.size(); ++e) {
    gp << DataFile(dir, "sweep", e) << " using 1:2 with linespoints ls " << (e % 12) + 1
       << " title " << Quote(labels[e]) << ", \\\n     ";
  }
  gp << Quote((fs::path(dir) / "floor.dat").string())
     << " using 1:2 with lines dt 2 lc rgb 'black' title 'floor'\n"
     << "unset logscale y\nset yrange [-1.05:1.05]\nset ylabel 'mean cosine to the reference'\n"
     << "set title 'direction'\nplot ";
  for (size_t e = 0; e < labels.size(); ++e) {
    gp << DataFile(dir, "sweep", e) << " using 1:3 with linespoints ls " << (e % 12) + 1
       << " title " << Quote(labels[e]) << (e + 1 < labels.size() ? ", \\\n     " : "\n");
  }
  gp << "unset multiplot\n";
  const std::string path = (fs::path(dir) / "horizon_sweep.gp").string();
  if (absl::Status st = io::WriteTextFile(path, gp.str()); !st.ok()) return st;
  written.push_back(path);
  return absl::OkStatus();
}

// Runs gnuplot on both scripts, once per picture type; the PNGs and PDFs
// are added to `written`.
absl::Status RunGnuplots(const std::string& dir, std::vector<std::string>& written) {
  namespace fs = std::filesystem;
  for (const char* script : {"work_precision", "horizon_sweep"}) {
    const std::string gp = (fs::path(dir) / absl::StrCat(script, ".gp")).string();
    for (const char* format : {"png", "pdf"}) {
      const std::string problem = RunGnuplot(gp, absl::StrCat("format = '", format, "'"));
      if (!problem.empty()) return absl::InternalError(problem);
      written.push_back((fs::path(dir) / absl::StrCat(script, ".", format)).string());
    }
  }
  return absl::OkStatus();
}

}  // namespace

absl::StatusOr<std::vector<std::string>> WriteStudyPlots(const study::StudyResult& r,
                                                         const StudySpec& spec,
                                                         const std::string& dir, bool run_gnuplot) {
  namespace fs = std::filesystem;
  std::error_code ec;
  fs::create_directories(dir, ec);
  if (ec) return absl::UnavailableError(absl::StrCat("cannot create '", dir, "': ", ec.message()));
  std::vector<std::string> written;
  const std::vector<int>& horizons = spec.options.horizons;
  const std::vector<std::string> labels = EstimatorLabels(r);
  const int sweep_p = SweepParticles(spec);
  if (absl::Status st = WriteDataFiles(r, horizons, labels, sweep_p, dir, written); !st.ok()) {
    return st;
  }
  if (absl::Status st = WriteWorkPrecisionScript(r, horizons, labels, dir, written); !st.ok()) {
    return st;
  }
  if (absl::Status st = WriteHorizonSweepScript(r, labels, sweep_p, dir, written); !st.ok()) {
    return st;
  }
  if (run_gnuplot) {
    if (absl::Status st = RunGnuplots(dir, written); !st.ok()) return st;
  }
  return written;
}

}  // namespace totalgrad::cli
