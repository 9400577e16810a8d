// `totalgrad bench trial`: the cost of one paper-protocol trial, measured on a
// shortened run and extrapolated.
//
// The run is the real protocol (same data growth N = H, 2H, ..., the GP
// training, the real and evaluation episodes) with K gradient steps per
// episode instead of the full F (600). A gradient step's cost depends on the
// sizes (N, P, H) and the method, not on the policy's values, so the full
// trial's CPU time is estimated as
//   measured CPU - policy CPU + policy CPU * F / K       (per episode)
// PILCO has no gradient steps (BFGS with its own budget): its run is the full
// protocol and nothing is extrapolated.
//
// Output: a table per episode and phase on stderr, one JSON document on
// stdout (and in --out FILE).
#include <cstdio>
#include <fstream>
#include <iostream>
#include <memory>
#include <string>
#include <thread>
#include <vector>

#include <nlohmann/json.hpp>

#include "client/core_commands/trial_flags.h"
#include "core/common/blas.h"
#include "core/learner/cost_model.h"
#include "core/learner/trial.h"

namespace totalgrad::cli {
namespace {

struct BenchTrialState {
  TrialFlagValues flags;
  int policy_steps = 30;
  int threads = 1;
  std::string out;
};

class CollectingObserver final : public learner::TrialObserver {
 public:
  void OnEpisode(const learner::EpisodeResult& result) override {
    episodes.push_back(result);
    std::fprintf(stderr, "  episode %d done (%.1f CPU s)\n", result.episode, result.cpu_seconds);
  }
  std::vector<learner::EpisodeResult> episodes;
};

std::string CpuModel() {
  std::ifstream in("/proc/cpuinfo");
  std::string line;
  while (std::getline(in, line)) {
    if (line.rfind("model name", 0) == 0) {
      const size_t colon = line.find(':');
      if (colon != std::string::npos) return line.substr(colon + 2);
    }
  }
  return "unknown";
}

// `bench trial`: runs the trial with --policy-steps steps per episode,
// prints the per-phase times (a table on stderr, JSON on stdout and in
// --out) and the CPU time extrapolated to the full protocol. Returns the
// exit code.
int RunBenchTrial(const BenchTrialState& state) {
  learner::TrialOptions options;
  const absl::Status valid = ApplyTrialOptionFlags(state.flags, &options);
  if (!valid.ok()) {
    std::cerr << "totalgrad bench trial: " << valid.message() << "\n";
    return 2;
  }
  const bool pilco = options.method == estimators::Method::kPilco;
  const int full_steps = options.policy_steps;
  const int run_steps = pilco ? full_steps : std::min(state.policy_steps, full_steps);
  options.policy_steps = run_steps;
  SetBlasThreads(1);
  CollectingObserver observer;
  learner::RunOptions run;
  run.threads = state.threads;
  std::fprintf(stderr, "bench trial: %s, %d of %d gradient steps per episode, %d thread(s)\n",
               estimators::MethodName(options.method).c_str(), pilco ? 0 : run_steps, pilco ? 0 : full_steps,
               state.threads);
  absl::StatusOr<learner::TrialSummary> summary = learner::RunTrial(options, &observer, run);
  if (!summary.ok()) {
    std::cerr << "totalgrad bench trial: the trial failed: " << summary.status().ToString() << "\n";
    return 1;
  }
  const double scale = (pilco || run_steps == 0) ? 1.0 : static_cast<double>(full_steps) / run_steps;
  nlohmann::json episodes = nlohmann::json::array();
  learner::EpisodeTiming sum;
  double measured_cpu = 0, measured_wall = 0, extrapolated_cpu = 0;
  std::fprintf(stderr,
               "%7s %6s %9s %9s %9s %9s %9s %9s %12s %12s\n", "episode", "N", "model", "policy",
               "predict", "real", "eval", "total", "cpu/step", "extrapolated");
  for (const learner::EpisodeResult& r : observer.episodes) {
    const learner::EpisodeTiming& t = r.timing;
    const int data = options.scene.horizon * r.episode;  // the data this episode's model saw
    const double per_step = t.policy_steps > 0 ? t.policy_cpu / t.policy_steps : 0.0;
    const double extrapolated = t.total_cpu() - t.policy_cpu + t.policy_cpu * scale;
    measured_cpu += t.total_cpu();
    measured_wall += t.total_wall();
    extrapolated_cpu += extrapolated;
    sum.model_cpu += t.model_cpu, sum.model_wall += t.model_wall;
    sum.policy_cpu += t.policy_cpu, sum.policy_wall += t.policy_wall;
    sum.prediction_cpu += t.prediction_cpu, sum.prediction_wall += t.prediction_wall;
    sum.real_episode_cpu += t.real_episode_cpu, sum.real_episode_wall += t.real_episode_wall;
    sum.evaluation_cpu += t.evaluation_cpu, sum.evaluation_wall += t.evaluation_wall;
    sum.policy_steps += t.policy_steps;
    std::fprintf(stderr, "%7d %6d %9.2f %9.2f %9.2f %9.2f %9.2f %9.2f %12.4f %12.1f\n",
                 r.episode, data, t.model_cpu, t.policy_cpu, t.prediction_cpu,
                 t.real_episode_cpu, t.evaluation_cpu, t.total_cpu(), per_step, extrapolated);
    episodes.push_back({{"episode", r.episode},
                        {"data", data},
                        {"model_cpu", t.model_cpu},
                        {"model_wall", t.model_wall},
                        {"policy_cpu", t.policy_cpu},
                        {"policy_wall", t.policy_wall},
                        {"policy_steps", t.policy_steps},
                        {"policy_cpu_per_step", per_step},
                        {"prediction_cpu", t.prediction_cpu},
                        {"prediction_wall", t.prediction_wall},
                        {"real_episode_cpu", t.real_episode_cpu},
                        {"real_episode_wall", t.real_episode_wall},
                        {"evaluation_cpu", t.evaluation_cpu},
                        {"evaluation_wall", t.evaluation_wall},
                        {"total_cpu", t.total_cpu()},
                        {"total_wall", t.total_wall()},
                        {"extrapolated_cpu", extrapolated}});
  }
  std::fprintf(stderr, "%7s %6s %9.2f %9.2f %9.2f %9.2f %9.2f %9.2f %12s %12.1f\n", "all", "",
               sum.model_cpu, sum.policy_cpu, sum.prediction_cpu, sum.real_episode_cpu,
               sum.evaluation_cpu, measured_cpu, "", extrapolated_cpu);
  std::fprintf(stderr, "measured %.1f CPU s (%.1f wall s); full protocol (%d steps): %.1f CPU s = %.2f CPU min\n",
               measured_cpu, measured_wall, full_steps, extrapolated_cpu, extrapolated_cpu / 60.0);
  nlohmann::json options_json = nlohmann::json::object();
  for (const auto& [key, value] : learner::TrialOptionPairs(options)) options_json[key] = value;
  options_json["policy_steps"] = std::to_string(full_steps);
  nlohmann::json doc = {
      {"method", estimators::MethodName(options.method)},
      {"options", options_json},
      {"policy_steps_run", pilco ? 0 : run_steps},
      {"policy_steps_full", pilco ? 0 : full_steps},
      {"extrapolated", !pilco},
      {"threads", state.threads},
      {"episodes", episodes},
      {"phases_cpu", {{"model", sum.model_cpu}, {"policy", sum.policy_cpu},
                      {"prediction", sum.prediction_cpu}, {"real_episodes", sum.real_episode_cpu},
                      {"evaluation", sum.evaluation_cpu}}},
      {"phases_wall", {{"model", sum.model_wall}, {"policy", sum.policy_wall},
                       {"prediction", sum.prediction_wall}, {"real_episodes", sum.real_episode_wall},
                       {"evaluation", sum.evaluation_wall}}},
      {"measured_cpu_seconds", measured_cpu},
      {"measured_wall_seconds", measured_wall},
      {"extrapolated_cpu_seconds", extrapolated_cpu},
      {"extrapolated_cpu_minutes", extrapolated_cpu / 60.0},
      {"final_eval_cost", summary->final_eval_cost},
      {"blas", BlasConfig()},
      {"cpu", CpuModel()}};
  std::cout << doc.dump(2) << std::endl;
  if (!state.out.empty()) {
    std::ofstream file(state.out);
    file << doc.dump(2) << "\n";
    if (!file) {
      std::cerr << "totalgrad bench trial: cannot write " << state.out << "\n";
      return 1;
    }
  }
  return 0;
}

}  // namespace

void AddBenchTrialCommand(CLI::App* bench, int* exit_code) {
  auto state = std::make_shared<BenchTrialState>();
  CLI::App* cmd = bench->add_subcommand(
      "trial",
      "CPU and wall seconds per phase of a paper-protocol trial run with --policy-steps K "
      "gradient steps per episode, and the CPU time extrapolated to the full protocol");
  cmd->add_option("--policy-steps", state->policy_steps,
                  "gradient steps per episode actually run (default 30); the full protocol's "
                  "count is the trial option policy_steps (600), set with --set policy_steps=F")
      ->check(CLI::Range(1, 1000000));
  cmd->add_option("--threads", state->threads, "threads for the trial (default 1)")
      ->check(CLI::Range(1, 256));
  cmd->add_option("--out", state->out, "also write the JSON document to this file");
  AddTrialOptionFlags(cmd, learner::TrialOptions(), &state->flags, {"policy_steps"});
  cmd->callback([state, exit_code]() { *exit_code = RunBenchTrial(*state); });
}

void AddBenchEstimateCommand(CLI::App* bench, int* exit_code) {
  auto flags = std::make_shared<TrialFlagValues>();
  CLI::App* cmd = bench->add_subcommand(
      "estimate",
      "the cost model's estimate of a trial's CPU seconds (docs/results/cost-model.md), no run");
  AddTrialOptionFlags(cmd, learner::TrialOptions(), flags.get());
  cmd->callback([flags, exit_code]() {
    learner::TrialOptions options;
    const absl::Status valid = ApplyTrialOptionFlags(*flags, &options);
    if (!valid.ok()) {
      std::cerr << "totalgrad bench estimate: " << valid.message() << "\n";
      *exit_code = 2;
      return;
    }
    const learner::TrialCostEstimate e = learner::EstimateTrialCost(options);
    nlohmann::json doc = {{"method", estimators::MethodName(options.method)},
                          {"policy_cpu_seconds", e.policy_cpu},
                          {"model_cpu_seconds", e.model_cpu},
                          {"other_cpu_seconds", e.other_cpu},
                          {"total_cpu_seconds", e.total_cpu()},
                          {"total_cpu_minutes", e.total_cpu() / 60.0},
                          {"reference_machine", learner::kReferenceMachine}};
    std::cout << doc.dump(2) << std::endl;
    *exit_code = 0;
  });
}

}  // namespace totalgrad::cli
