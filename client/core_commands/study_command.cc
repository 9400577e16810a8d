// `totalgrad study FILE`: a gradient study (core/study/study.h) described by a
// JSON file (io/study_file.h), printed as a table (study_format.h: text, CSV
// or JSON) and, with --output-dir, written there with log-log
// work-precision plots (study_plots.h: gnuplot, PNG).
// `totalgrad study summary LABEL=RESULTS ...`: the equal-time summary of
// finished studies (study_summary.h, core/study/equal_time.h).
#include <filesystem>
#include <fstream>
#include <iostream>
#include <cmath>
#include <memory>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include "absl/strings/numbers.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_split.h"
#include "client/core_commands/commands.h"
#include "client/core_commands/study_format.h"
#include "client/core_commands/study_plots.h"
#include "client/core_commands/study_summary.h"
#include "core/common/blas.h"
#include "io/study_file.h"
#include "io/study_results.h"
#include "io/text_file.h"

namespace totalgrad::cli {
namespace {

using io::LoadStudyProblem;
using io::ParseStudySpec;
using io::StudySpec;

using Json = nlohmann::json;

struct StudySummaryState {
  std::vector<std::string> studies;  // LABEL=PATH
  std::string seconds = "0.01,0.1,1";
  std::string format = "markdown";
};

// `study summary`: reads each LABEL=PATH (a results.json or its directory)
// and prints the equal-time tables.
void RunStudySummary(const StudySummaryState& state, int* exit_code) {
  auto fail = [exit_code](const std::string& message) {
    std::cerr << "totalgrad study summary: " << message << "\n";
    *exit_code = 2;
  };
  std::vector<double> seconds;
  for (absl::string_view part : absl::StrSplit(state.seconds, ',')) {
    double v = 0;
    if (!absl::SimpleAtod(part, &v) || !(v > 0) || !std::isfinite(v)) {
      return fail(absl::StrCat("--seconds: '", part, "' is not a positive number"));
    }
    seconds.push_back(v);
  }
  std::vector<LabelledStudy> studies;
  for (const std::string& item : state.studies) {
    const size_t eq = item.find('=');
    if (eq == std::string::npos || eq == 0 || eq + 1 == item.size()) {
      return fail(absl::StrCat("'", item, "': expected LABEL=PATH (a results.json or its directory)"));
    }
    absl::StatusOr<study::StudyResult> result = io::ReadStudyResultFile(item.substr(eq + 1));
    if (!result.ok()) return fail(std::string(result.status().message()));
    studies.push_back({item.substr(0, eq), *std::move(result)});
  }
  if (state.format == "json") std::cout << StudySummaryJson(studies, seconds).dump(2) << "\n";
  else std::cout << StudySummaryMarkdown(studies, seconds);
  *exit_code = 0;
}

struct StudyCommandState {
  std::string file;
  std::string format = "text";
  std::string output_dir;
  bool no_plots = false;
  bool quiet = false;
};

}  // namespace

void AddStudyCommand(CLI::App* app, int* exit_code) {
  auto state = std::make_shared<StudyCommandState>();
  CLI::App* cmd = app->add_subcommand(
      "study", "Gradient error against run time for every estimator on a frozen problem "
               "(docs/error-vs-time.md)");
  // Not ->required(): `study summary` takes no study file (checked below).
  cmd->add_option("file", state->file, "study file (JSON; format in io/study_file.h)");
  cmd->add_option("--format", state->format, "stdout format: text, csv or json (default text)")
      ->check(CLI::IsMember({"text", "csv", "json"}));
  cmd->add_option("--output-dir", state->output_dir,
                  "also write table.txt, table.csv, references.csv, results.json and the plots here");
  cmd->add_flag("--no-plots", state->no_plots, "with --output-dir: write the gnuplot scripts but do not run gnuplot");
  cmd->add_flag("--quiet", state->quiet, "no progress lines on stderr");
  auto summary_state = std::make_shared<StudySummaryState>();
  CLI::App* summary = cmd->add_subcommand(
      "summary",
      "Per horizon and time per gradient, the estimator with the lowest error and every other's "
      "error ratio to it (docs/error-vs-time.md)");
  summary
      ->add_option("studies", summary_state->studies,
                   "LABEL=PATH, PATH a study's results.json or the --output-dir holding it")
      ->required();
  summary->add_option("--seconds", summary_state->seconds,
                      "comma-separated seconds per gradient (default 0.01,0.1,1)");
  summary->add_option("--format", summary_state->format, "markdown (default) or json")
      ->check(CLI::IsMember({"markdown", "json"}));
  summary->callback([summary_state, exit_code]() { RunStudySummary(*summary_state, exit_code); });
  cmd->callback([state, exit_code, summary]() {
    if (summary->parsed()) return;  // the subcommand did the work
    if (state->file.empty()) {
      std::cerr << "totalgrad study: a study file is required (or `study summary ...`)\n";
      *exit_code = 2;
      return;
    }
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
      for (absl::Status st : {io::WriteTextFile((dir / "table.txt").string(), StudyTableText(*result)),
                              io::WriteTextFile((dir / "table.csv").string(), StudyTableCsv(*result)),
                              io::WriteTextFile((dir / "references.csv").string(), StudyReferenceCsv(*result)),
                              io::WriteTextFile((dir / "results.json").string(),
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
