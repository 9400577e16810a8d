#include "io/study_file.h"

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <map>
#include <sstream>

#include <CLI/CLI.hpp>

#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"
#include "absl/strings/str_join.h"
#include "client/core_commands/commands.h"
#include "io/snapshot_json.h"
#include "core/common/blas.h"
#include "core/learner/trial.h"

namespace totalgrad::cli {
namespace {

using io::InlineStudyDocument;
using io::LoadStudyProblem;
using io::ParseStudySpec;
using io::ReadStudyDocument;
using io::StudyCellNote;
using io::StudySpec;

using Json = nlohmann::json;
using OrderedJson = nlohmann::ordered_json;

std::string Num(double v, const char* format = "%.3g") {
  return std::isfinite(v) ? absl::StrFormat(format, v) : std::string("-");
}

OrderedJson JsonNumber(double v) { return std::isfinite(v) ? OrderedJson(v) : OrderedJson(nullptr); }

OrderedJson VectorJson(const Vector& v) {
  OrderedJson a = OrderedJson::array();
  for (Eigen::Index i = 0; i < v.size(); ++i) a.push_back(JsonNumber(v(i)));
  return a;
}

const study::ReferenceGradient* ReferenceFor(const study::StudyResult& r, int horizon) {
  for (const auto& ref : r.references) {
    if (ref.horizon == horizon) return &ref;
  }
  return nullptr;
}

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

absl::Status WriteFile(const std::string& path, const std::string& text) {
  std::ofstream out(path);
  if (!out) return absl::UnavailableError(absl::StrCat("cannot write '", path, "'"));
  out << text;
  if (!out) return absl::UnavailableError(absl::StrCat("error writing '", path, "'"));
  return absl::OkStatus();
}

struct StudyCommandState {
  std::string file;
  std::string format = "text";
  std::string output_dir;
  bool no_plots = false;
  bool quiet = false;
};

}  // namespace

std::string StudyTableText(const study::StudyResult& r) {
  std::ostringstream os;
  os << "problem: " << r.source << "; " << r.num_parameters << " policy parameters; study "
     << Num(r.seconds, "%.1f") << " s\n\n";
  os << "reference gradients (pooled; floor = 1.96 |SE| / |g*|):\n";
  os << absl::StrFormat("%5s %10s %9s %8s %9s %-28s %8s %8s %5s  %s\n", "H", "|g*|", "rel_SE",
                        "floor", "J", "estimators (replicates)", "max|z|", "mean_z2", "agree", "note");
  for (const auto& ref : r.references) {
    std::vector<std::string> used;
    for (size_t k = 0; k < ref.used.size(); ++k) {
      used.push_back(absl::StrCat(ref.used[k], " (", ref.replicates[k], ")"));
    }
    os << absl::StrFormat("%5d %10s %9s %8s %9s %-28s %8s %8s %5s  %s\n", ref.horizon,
                          Num(ref.norm, "%.4g"), Num(ref.relative_error), Num(ref.floor),
                          Num(ref.objective, "%.4g"), absl::StrJoin(used, ", "),
                          Num(ref.agreement_max_z), Num(ref.agreement_mean_z2),
                          ref.agree ? "yes" : "NO", ref.note);
  }
  os << "\n";
  os << absl::StrFormat("%-14s %5s %4s %5s %10s %9s %9s %9s %7s %7s %7s %6s %5s  %s\n", "estimator",
                        "P", "H", "reps", "t_min_ms", "rel_rmse", "rel_bias", "bias_noise", "cos",
                        "ess", "k_lr", "nonfin", "err", "note");
  std::vector<std::string> omissions;
  for (const auto& c : r.cells) {
    os << absl::StrFormat("%-14s %5s %4d %5d %10s %9s %9s %9s %7s %7s %7s %6d %5d  %s\n", c.estimator,
                          c.particles > 0 ? std::to_string(c.particles) : "-", c.horizon,
                          c.replicates, Num(c.time_min_s * 1e3, "%.4g"), Num(c.rel_rmse),
                          Num(c.rel_bias), Num(c.rel_bias_noise), Num(c.cos_mean, "%.3f"),
                          Num(c.ess_mean, "%.3f"), Num(c.k_lr_mean, "%.3f"), c.nonfinite, c.errors,
                          StudyCellNote(c));
    if (c.omitted || !c.reference_agrees || c.nonfinite > 0 || c.errors > 0) {
      omissions.push_back(absl::StrCat(c.estimator, " P=", c.particles, " H=", c.horizon, ": ",
                                       c.omitted ? c.omission_reason
                                                 : absl::StrCat(c.nonfinite, " non-finite, ",
                                                                c.errors, " errors"),
                                       c.reference_agrees ? "" : " (reference disagrees: not plotted)"));
    }
  }
  if (!omissions.empty()) {
    os << "\nomissions and failures:\n";
    for (const auto& line : omissions) os << "  " << line << "\n";
  }
  return os.str();
}

std::string StudyTableCsv(const study::StudyResult& r) {
  std::ostringstream os;
  os << "estimator,method,particles,horizon,replicates,nonfinite,errors,time_min_s,time_median_s,"
        "rel_rmse,rel_bias,rel_bias_noise,total_variance,cos_mean,objective_mean,ess_mean,ess_min,"
        "k_lr_mean,reference_agrees,reference_floor,budget_hit,omitted,note\n";
  auto csv = [](double v) { return std::isfinite(v) ? absl::StrFormat("%.9g", v) : std::string(); };
  auto text = [](std::string s) {
    for (char& ch : s) {
      if (ch == '"') ch = '\'';
    }
    return "\"" + s + "\"";
  };
  for (const auto& c : r.cells) {
    const study::ReferenceGradient* ref = ReferenceFor(r, c.horizon);
    os << text(c.estimator) << "," << text(c.method) << "," << c.particles << "," << c.horizon << ","
       << c.replicates << "," << c.nonfinite << "," << c.errors << "," << csv(c.time_min_s) << ","
       << csv(c.time_median_s) << "," << csv(c.rel_rmse) << "," << csv(c.rel_bias) << ","
       << csv(c.rel_bias_noise) << "," << csv(c.total_variance) << "," << csv(c.cos_mean) << ","
       << csv(c.objective_mean) << "," << csv(c.ess_mean) << "," << csv(c.ess_min) << ","
       << csv(c.k_lr_mean) << "," << (c.reference_agrees ? 1 : 0) << ","
       << csv(ref != nullptr ? ref->floor : study::CellResult::kNaN) << "," << (c.budget_hit ? 1 : 0)
       << "," << (c.omitted ? 1 : 0) << "," << text(StudyCellNote(c)) << "\n";
  }
  return os.str();
}

std::string StudyReferenceCsv(const study::StudyResult& r) {
  std::ostringstream os;
  os << "horizon,norm,relative_error,floor,objective,used,replicates,agreement_max_z,"
        "agreement_mean_z2,agree,seconds,note\n";
  for (const auto& ref : r.references) {
    std::vector<std::string> reps;
    for (int n : ref.replicates) reps.push_back(std::to_string(n));
    os << ref.horizon << "," << absl::StrFormat("%.9g,%.9g,%.9g,%.9g", ref.norm, ref.relative_error,
                                                ref.floor, ref.objective)
       << ",\"" << absl::StrJoin(ref.used, ";") << "\",\"" << absl::StrJoin(reps, ";") << "\","
       << absl::StrFormat("%.6g,%.6g", ref.agreement_max_z, ref.agreement_mean_z2) << ","
       << (ref.agree ? 1 : 0) << "," << absl::StrFormat("%.3f", ref.seconds) << ",\"" << ref.note
       << "\"\n";
  }
  return os.str();
}

OrderedJson StudyToJson(const study::StudyResult& r, const StudySpec& spec) {
  OrderedJson j;
  j["source"] = r.source;
  j["num_parameters"] = r.num_parameters;
  j["seconds"] = r.seconds;
  j["blas"] = BlasConfig();
  const study::StudyOptions& o = spec.options;
  OrderedJson estimators = OrderedJson::array();
  for (const auto& e : o.estimators) estimators.push_back(e.label);
  OrderedJson ref_estimators = OrderedJson::array();
  for (const auto& e : o.reference.estimators) ref_estimators.push_back(e.label);
  j["options"] = {{"estimators", estimators},
                  {"particles", o.particles},
                  {"horizons", o.horizons},
                  {"replicates", o.replicates},
                  {"seed", o.seed},
                  {"cell_budget_seconds", o.cell_budget_seconds},
                  {"ess_replicates", o.ess_replicates},
                  {"reference", {{"estimators", ref_estimators},
                                 {"particles", o.reference.particles},
                                 {"replicates", o.reference.replicates},
                                 {"agreement_max_z", o.reference.agreement_max_z},
                                 {"agreement_mean_z2", o.reference.agreement_mean_z2}}}};
  OrderedJson refs = OrderedJson::array();
  for (const auto& ref : r.references) {
    refs.push_back({{"horizon", ref.horizon},
                    {"norm", JsonNumber(ref.norm)},
                    {"relative_error", JsonNumber(ref.relative_error)},
                    {"floor", JsonNumber(ref.floor)},
                    {"objective", JsonNumber(ref.objective)},
                    {"used", ref.used},
                    {"replicates", ref.replicates},
                    {"agreement_max_z", JsonNumber(ref.agreement_max_z)},
                    {"agreement_mean_z2", JsonNumber(ref.agreement_mean_z2)},
                    {"agree", ref.agree},
                    {"note", ref.note},
                    {"seconds", ref.seconds},
                    {"gradient", VectorJson(ref.gradient)},
                    {"standard_error", VectorJson(ref.standard_error)}});
  }
  j["references"] = refs;
  OrderedJson cells = OrderedJson::array();
  for (const auto& c : r.cells) {
    OrderedJson k_lr = OrderedJson::array();
    for (double v : c.k_lr_per_step) k_lr.push_back(JsonNumber(v));
    cells.push_back({{"estimator", c.estimator},
                     {"method", c.method},
                     {"particles", c.particles},
                     {"horizon", c.horizon},
                     {"replicates", c.replicates},
                     {"nonfinite", c.nonfinite},
                     {"errors", c.errors},
                     {"error", c.error},
                     {"budget_hit", c.budget_hit},
                     {"omitted", c.omitted},
                     {"omission_reason", c.omission_reason},
                     {"time_min_s", JsonNumber(c.time_min_s)},
                     {"time_median_s", JsonNumber(c.time_median_s)},
                     {"rel_rmse", JsonNumber(c.rel_rmse)},
                     {"rel_bias", JsonNumber(c.rel_bias)},
                     {"rel_bias_noise", JsonNumber(c.rel_bias_noise)},
                     {"total_variance", JsonNumber(c.total_variance)},
                     {"cos_mean", JsonNumber(c.cos_mean)},
                     {"objective_mean", JsonNumber(c.objective_mean)},
                     {"ess_mean", JsonNumber(c.ess_mean)},
                     {"ess_min", JsonNumber(c.ess_min)},
                     {"k_lr_mean", JsonNumber(c.k_lr_mean)},
                     {"k_lr_per_step", k_lr},
                     {"reference_agrees", c.reference_agrees}});
  }
  j["cells"] = cells;
  return j;
}

absl::StatusOr<std::vector<std::string>> WriteStudyPlots(const study::StudyResult& r,
                                                         const StudySpec& spec,
                                                         const std::string& dir, bool run_gnuplot) {
  namespace fs = std::filesystem;
  std::error_code ec;
  fs::create_directories(dir, ec);
  if (ec) return absl::UnavailableError(absl::StrCat("cannot create '", dir, "': ", ec.message()));
  std::vector<std::string> written;
  const std::vector<int>& horizons = spec.options.horizons;
  std::vector<std::string> labels;
  for (const auto& c : r.cells) {
    if (std::find(labels.begin(), labels.end(), c.estimator) == labels.end()) labels.push_back(c.estimator);
  }
  // The horizon sweep's P: the requested one, else the study's nearest.
  int sweep_p = spec.sweep_particles;
  {
    int best = -1;
    for (int p : spec.options.particles) {
      if (best < 0 || std::abs(std::log(static_cast<double>(p) / sweep_p)) <
                          std::abs(std::log(static_cast<double>(best) / sweep_p))) {
        best = p;
      }
    }
    sweep_p = best;
  }

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
    if (absl::Status st = WriteFile(wp_path, wp.str()); !st.ok()) return st;
    if (absl::Status st = WriteFile(sweep_path, sweep.str()); !st.ok()) return st;
    written.push_back(wp_path);
    written.push_back(sweep_path);
  }
  {
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
    if (absl::Status st = WriteFile(path, floor.str()); !st.ok()) return st;
    written.push_back(path);
  }

  // Work-precision: one panel per horizon.
  const int n = static_cast<int>(horizons.size());
  const int cols = n <= 1 ? 1 : 2;
  const int rows = (n + cols - 1) / cols;
  const std::string styles =
      "set style line 1 lc rgb '#1f77b4' pt 7\nset style line 2 lc rgb '#ff7f0e' pt 5\n"
      "set style line 3 lc rgb '#2ca02c' pt 9\nset style line 4 lc rgb '#d62728' pt 11\n"
      "set style line 5 lc rgb '#9467bd' pt 13\nset style line 6 lc rgb '#8c564b' pt 4\n"
      "set style line 7 lc rgb '#e377c2' pt 6\nset style line 8 lc rgb '#7f7f7f' pt 8\n"
      "set style line 9 lc rgb '#bcbd22' pt 10\nset style line 10 lc rgb '#17becf' pt 12\n"
      "set style line 11 lc rgb '#000000' pt 3\nset style line 12 lc rgb '#aaaa00' pt 1\n";
  auto dat = [&](const std::string& stem, size_t e) {
    return Quote((fs::path(dir) / absl::StrCat(stem, "_", e, ".dat")).string());
  };
  {
    std::ostringstream gp;
    gp << "# Work-precision diagram of a gradient study (totalgrad study).\n"
       << "# Problem: " << r.source << "\n"
       << "set terminal pngcairo noenhanced size " << 620 * cols << "," << 470 * rows
       << " font ',9'\n"
       << "set output " << Quote((fs::path(dir) / "work_precision.png").string()) << "\n"
       << styles << "set logscale xy\nset format x '%.0e'\nset format y '%g'\n"
       << "set xlabel 'seconds per gradient (min of single-threaded runs)'\n"
       << "set ylabel 'relative RMSE vs reference'\nset grid\nset key outside right top\n"
       << "set multiplot layout " << rows << "," << cols
       << " title 'error against run time, one curve per estimator (points: P); dashed: reference noise floor'\n";
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
        gp << dat("wp", e) << " index " << hi << " using 2:3 with linespoints ls "
           << (e % 12) + 1 << " title " << Quote(labels[e]) << ", \\\n     ";
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
    if (absl::Status st = WriteFile(path, gp.str()); !st.ok()) return st;
    written.push_back(path);
  }
  // Horizon sweep at fixed P: error and direction against H.
  {
    std::ostringstream gp;
    gp << "# Horizon sweep at P = " << sweep_p << " (PILCO: its single value per H).\n"
       << "# Problem: " << r.source << "\n"
       << "set terminal pngcairo noenhanced size 1240,470 font ',9'\n"
       << "set output " << Quote((fs::path(dir) / "horizon_sweep.png").string()) << "\n"
       << styles << "set grid\nset key outside right top\nset xlabel 'horizon H (steps)'\n"
       << "set multiplot layout 1,2 title 'horizon sweep at P = " << sweep_p << "'\n";
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
      gp << dat("sweep", e) << " using 1:2 with linespoints ls " << (e % 12) + 1 << " title "
         << Quote(labels[e]) << ", \\\n     ";
    }
    gp << Quote((fs::path(dir) / "floor.dat").string())
       << " using 1:2 with lines dt 2 lc rgb 'black' title 'floor'\n"
       << "unset logscale y\nset yrange [-1.05:1.05]\nset ylabel 'mean cosine to the reference'\n"
       << "set title 'direction'\nplot ";
    for (size_t e = 0; e < labels.size(); ++e) {
      gp << dat("sweep", e) << " using 1:3 with linespoints ls " << (e % 12) + 1 << " title "
         << Quote(labels[e]) << (e + 1 < labels.size() ? ", \\\n     " : "\n");
    }
    gp << "unset multiplot\n";
    const std::string path = (fs::path(dir) / "horizon_sweep.gp").string();
    if (absl::Status st = WriteFile(path, gp.str()); !st.ok()) return st;
    written.push_back(path);
  }
  if (run_gnuplot) {
    for (const char* script : {"work_precision", "horizon_sweep"}) {
      const std::string gp = (fs::path(dir) / absl::StrCat(script, ".gp")).string();
      const std::string command = absl::StrCat("gnuplot ", Quote(gp), " 2>&1");
      FILE* pipe = popen(command.c_str(), "r");
      if (pipe == nullptr) return absl::UnavailableError("cannot run gnuplot");
      std::string output;
      char buffer[256];
      while (fgets(buffer, sizeof(buffer), pipe) != nullptr) output += buffer;
      const int rc = pclose(pipe);
      if (rc != 0) {
        return absl::InternalError(absl::StrCat("gnuplot failed on '", gp, "' (status ", rc,
                                                "): ", output));
      }
      written.push_back((fs::path(dir) / absl::StrCat(script, ".png")).string());
    }
  }
  return written;
}

void AddStudyCommand(CLI::App* app, int* exit_code) {
  auto state = std::make_shared<StudyCommandState>();
  CLI::App* cmd = app->add_subcommand(
      "study", "Gradient error against run time for every estimator on a frozen problem "
               "(docs/error-vs-time.md)");
  cmd->add_option("file", state->file, "study file (JSON; format in io/study_file.h)")
      ->required();
  cmd->add_option("--format", state->format, "stdout format: text, csv or json (default text)")
      ->check(CLI::IsMember({"text", "csv", "json"}));
  cmd->add_option("--output-dir", state->output_dir,
                  "also write table.txt, table.csv, references.csv, results.json and the plots here");
  cmd->add_flag("--no-plots", state->no_plots, "with --output-dir: write the gnuplot scripts but do not run gnuplot");
  cmd->add_flag("--quiet", state->quiet, "no progress lines on stderr");
  cmd->callback([state, exit_code]() {
    std::ifstream in(state->file);
    if (!in) {
      std::cerr << "totalgrad study: cannot open '" << state->file << "'\n";
      *exit_code = 2;
      return;
    }
    const Json doc = Json::parse(in, nullptr, /*allow_exceptions=*/false);
    if (doc.is_discarded()) {
      std::cerr << "totalgrad study: '" << state->file << "' is not valid JSON\n";
      *exit_code = 2;
      return;
    }
    const std::string base_dir = std::filesystem::path(state->file).parent_path().string();
    absl::StatusOr<StudySpec> spec = ParseStudySpec(doc, base_dir);
    if (!spec.ok()) {
      std::cerr << "totalgrad study: " << spec.status().message() << "\n";
      *exit_code = 2;
      return;
    }
    absl::StatusOr<std::unique_ptr<study::FrozenProblem>> problem = LoadStudyProblem(*spec);
    if (!problem.ok()) {
      std::cerr << "totalgrad study: " << problem.status().message() << "\n";
      *exit_code = problem.status().code() == absl::StatusCode::kInvalidArgument ||
                           problem.status().code() == absl::StatusCode::kNotFound
                       ? 2
                       : 1;
      return;
    }
    SetBlasThreads(1);  // timings are of single-threaded runs
    const bool quiet = state->quiet;
    absl::StatusOr<study::StudyResult> result =
        study::RunStudy(**problem, spec->options, [quiet](const std::string& line) {
          if (!quiet) std::cerr << line << std::endl;
        });
    if (!result.ok()) {
      std::cerr << "totalgrad study: " << result.status().message() << "\n";
      *exit_code = 1;
      return;
    }
    if (state->format == "csv") std::cout << StudyTableCsv(*result);
    else if (state->format == "json") std::cout << StudyToJson(*result, *spec).dump(2) << "\n";
    else std::cout << StudyTableText(*result);
    if (!state->output_dir.empty()) {
      namespace fs = std::filesystem;
      std::error_code ec;
      fs::create_directories(state->output_dir, ec);
      const fs::path dir(state->output_dir);
      for (absl::Status st : {WriteFile((dir / "table.txt").string(), StudyTableText(*result)),
                              WriteFile((dir / "table.csv").string(), StudyTableCsv(*result)),
                              WriteFile((dir / "references.csv").string(), StudyReferenceCsv(*result)),
                              WriteFile((dir / "results.json").string(),
                                        StudyToJson(*result, *spec).dump(2) + "\n")}) {
        if (!st.ok()) {
          std::cerr << "totalgrad study: " << st.message() << "\n";
          *exit_code = 1;
          return;
        }
      }
      absl::StatusOr<std::vector<std::string>> plots =
          WriteStudyPlots(*result, *spec, state->output_dir, !state->no_plots);
      if (!plots.ok()) {
        std::cerr << "totalgrad study: plots: " << plots.status().message() << "\n";
        *exit_code = 1;
        return;
      }
    }
    *exit_code = 0;
  });
}

}  // namespace totalgrad::cli
