// `totalgrad trial`: one policy-learning trial in-process, printing each
// episode as it finishes.
#include <cmath>
#include <cstdio>
#include <iostream>
#include <map>
#include <memory>
#include <set>
#include <string>
#include <utility>
#include <vector>

#include <nlohmann/json.hpp>

#include "absl/strings/str_replace.h"
#include "client/core_commands/commands.h"
#include "client/core_commands/trial_flags.h"
#include "io/episode_json.h"
#include "io/snapshot_json.h"
#include "client/core_commands/trial_format.h"
#include "core/common/blas.h"
#include "core/learner/trial.h"

namespace totalgrad::cli {
namespace {

class PrintingObserver final : public learner::TrialObserver {
 public:
  // Snapshots of `snapshot_episodes` are written to `snapshot_file` (the
  // whole file again after each one, so a cut-short trial keeps the earlier
  // ones).
  PrintingObserver(bool json, std::set<int> snapshot_episodes, std::string snapshot_file)
      : json_(json), snapshot_episodes_(std::move(snapshot_episodes)),
        snapshot_file_(std::move(snapshot_file)) {}
  bool WantsSnapshot(int episode) override { return snapshot_episodes_.count(episode) > 0; }
  void OnSnapshot(const learner::TrialSnapshot& snapshot) override {
    snapshots_.push_back(snapshot);
    const absl::Status st = io::WriteSnapshotFile(snapshot_file_, snapshots_);
    if (!st.ok()) {
      std::cerr << "totalgrad trial: snapshot of episode " << snapshot.episode << ": " << st.message()
                << "\n";
      snapshot_failed_ = true;
    }
  }
  bool snapshot_failed() const { return snapshot_failed_; }
  int snapshots_written() const { return static_cast<int>(snapshots_.size()); }
  void OnEpisode(const learner::EpisodeResult& result) override {
    if (json_) {
      std::cout << io::EpisodeToJson(result).dump() << std::endl;
    } else {
      if (!header_printed_) {
        std::printf("%-8s %10s %10s %10s %10s %10s  %s\n", "episode", "real_cost", "eval_mean",
                    "eval_std", "predicted", "seconds", "flags");
        header_printed_ = true;
      }
      std::printf("%-8d %10.3f %10.3f %10.3f %10.3f %10.1f  %s\n", result.episode, result.real_cost,
                  result.eval_cost_mean, result.eval_cost_std, result.predicted_cost,
                  result.optimisation_seconds, FlagsText(result.flags).c_str());
      std::fflush(stdout);
    }
  }

 private:
  bool json_;
  bool header_printed_ = false;
  std::set<int> snapshot_episodes_;
  std::string snapshot_file_;
  std::vector<learner::TrialSnapshot> snapshots_;
  bool snapshot_failed_ = false;
};

struct TrialCommandState {
  TrialFlagValues flags;
  int threads = 1;
  bool json = false;
  std::string snapshot_episodes;  // "1,5,10"
  std::string snapshot_file = "snapshots.json";
};

}  // namespace

void AddTrialCommand(CLI::App* app, int* exit_code) {
  auto state = std::make_shared<TrialCommandState>();
  CLI::App* cmd = app->add_subcommand(
      "trial", "Run one policy-learning trial in-process and print each episode as it finishes");
  cmd->add_flag("--json", state->json, "print one JSON object per episode instead of a table");
  // Every trial option is a flag of its own: key noise_k is --noise-k.
  AddTrialOptionFlags(cmd, learner::TrialOptions(), &state->flags);
  cmd->add_option("--threads", state->threads,
                  "threads for this trial (default 1); the results are the same bits for any value")
      ->check(CLI::Range(1, 256));
  cmd->add_option("--snapshot-episodes", state->snapshot_episodes,
                  "save the model data, hyperparameters and policy at these learned episodes "
                  "(e.g. 1,5,10) for `totalgrad study`");
  cmd->add_option("--snapshot-file", state->snapshot_file,
                  "where --snapshot-episodes writes (default snapshots.json)");
  cmd->callback([state, exit_code]() {
    learner::TrialOptions options;
    const absl::Status valid = ApplyTrialOptionFlags(state->flags, &options);
    if (!valid.ok()) {
      std::cerr << "totalgrad trial: " << valid.message() << "\n";
      *exit_code = 2;
      return;
    }
    std::set<int> snapshot_episodes;
    if (!state->snapshot_episodes.empty()) {
      absl::StatusOr<std::vector<int>> episodes = io::ParseEpisodeList(state->snapshot_episodes);
      if (!episodes.ok()) {
        std::cerr << "totalgrad trial: --snapshot-episodes: " << episodes.status().message() << "\n";
        *exit_code = 2;
        return;
      }
      snapshot_episodes.insert(episodes->begin(), episodes->end());
    }
    SetBlasThreads(1);  // a trial is single-threaded by contract (determinism)
    PrintingObserver observer(state->json, snapshot_episodes, state->snapshot_file);
    learner::RunOptions run;
    run.threads = state->threads;
    absl::StatusOr<learner::TrialSummary> summary = learner::RunTrial(options, &observer, run);
    if (!summary.ok()) {
      std::cerr << "totalgrad trial: failed: " << summary.status().ToString() << "\n";
      *exit_code = 1;
      return;
    }
    if (observer.snapshot_failed()) {
      *exit_code = 1;
      return;
    }
    if (!snapshot_episodes.empty() && observer.snapshots_written() < static_cast<int>(snapshot_episodes.size())) {
      std::cerr << "totalgrad trial: note: " << observer.snapshots_written() << " of "
                << snapshot_episodes.size() << " requested snapshots taken (episodes beyond "
                << options.episodes << " do not exist)\n";
    }
    if (state->json) {
      nlohmann::json done = {{"done", true}};
      done.update(io::TrialSummaryJson(*summary, options));
      done["threads"] = state->threads;
      std::cout << done.dump() << std::endl;
    } else {
      std::printf("final evaluation cost %.3f (threshold %.3g): %s\n", summary->final_eval_cost,
                  options.success_threshold, summary->success ? "success" : "failure");
      const double held = summary->episodes.back().held_fraction;
      if (!std::isnan(held)) {
        std::printf("rollout verdict: held in %.0f%% of %d rollouts of the final policy: %s\n",
                    100 * held, options.verdict_rollouts, held >= 0.5 ? "held" : "not held");
      }
    }
    *exit_code = 0;
  });
}

}  // namespace totalgrad::cli
