// Registration of the in-process `totalgrad` subcommands (no service needed).
//
// Each Add*Command adds one subcommand to `app`; the subcommand's callback
// runs it and stores the process exit code in *exit_code (0 = success,
// 1 = the run failed, 2 = bad usage/input). Errors go to stderr with the
// cause named; results go to stdout.
#ifndef TOTALGRAD_CLIENT_CORE_COMMANDS_COMMANDS_H_
#define TOTALGRAD_CLIENT_CORE_COMMANDS_COMMANDS_H_

#include <CLI/CLI.hpp>

#include <algorithm>
#include <vector>

namespace totalgrad::cli {

void AddSimulateCommand(CLI::App* app, int* exit_code);  // simulate_command.cc
void AddTrialCommand(CLI::App* app, int* exit_code);     // trial_command.cc
void AddBenchCommand(CLI::App* app, int* exit_code);     // bench_command.cc
// `bench trial`, added under the `bench` subcommand by AddBenchCommand.
void AddBenchTrialCommand(CLI::App* bench, int* exit_code);  // bench_trial_command.cc
// `bench estimate`, likewise (bench_trial_command.cc).
void AddBenchEstimateCommand(CLI::App* bench, int* exit_code);
// `bench gradients`, likewise.
void AddBenchGradientsCommand(CLI::App* bench, int* exit_code);  // bench_gradients_command.cc
void AddPilcoCommand(CLI::App* app, int* exit_code);     // pilco_command.cc
void AddStudyCommand(CLI::App* app, int* exit_code);     // study_command.cc
void AddEvaluateCommand(CLI::App* app, int* exit_code);  // evaluate_command.cc
void AddScenesCommand(CLI::App* app, int* exit_code);    // scenes_command.cc

// The bench commands' median of timings: the upper middle element of an
// even count, as every committed bench JSON was computed. `times` not empty.
inline double BenchMedian(std::vector<double> times) {
  std::sort(times.begin(), times.end());
  return times[times.size() / 2];
}

}  // namespace totalgrad::cli

#endif  // TOTALGRAD_CLIENT_CORE_COMMANDS_COMMANDS_H_
