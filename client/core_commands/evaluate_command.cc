// `totalgrad evaluate`: a saved policy (a trial snapshot file, e.g. from
// `totalgrad job artifacts` or `totalgrad trial --snapshot-file`) run on the
// real plant, as the trial evaluates its policies (learner::EvaluatePolicy).
//
//   totalgrad evaluate --policy out/snapshot.json --rollouts 30
//   totalgrad evaluate --policy out/snapshot.json --rollouts 100 --noise-k 0.5 --seed 7 --json
//
// By default rollout r uses the trial's own evaluation streams of the
// snapshot's episode, so `--rollouts <eval_rollouts>` reproduces the trial's
// evaluation of that policy exactly; --seed/--episode pick other draws, and
// --scene/--cost/--noise-k/--set change the task the policy is tried on.
// --states FILE.csv also writes every rollout step by step (the true states
// in the scene's state order, the controls applied, the step's cost), e.g.
// to look at what a policy with a given evaluation cost actually does.
// --classify also gives each rollout's rollout verdict (held or not: the goal
// distance within verdict_distance over the last verdict_hold_seconds) and
// the fraction held, as a trial classifies its final policy.
#include <iostream>
#include <memory>
#include <string>
#include <vector>

#include <CLI/CLI.hpp>
#include <nlohmann/json.hpp>

#include "absl/strings/str_cat.h"
#include "client/core_commands/commands.h"
#include "core/learner/evaluation.h"
#include "io/record_format.h"
#include "io/snapshot_json.h"
#include "io/text_file.h"

namespace totalgrad::cli {
namespace {

struct EvaluateFlags {
  std::string policy_file;
  int snapshot_episode = -1;  // -1: the file's last snapshot
  std::string scene, cost, noise_k, seed;
  std::vector<std::string> sets;
  int episode = -1;  // evaluation streams of this episode; -1: the snapshot's
  int rollouts = 0;
  bool json = false;
  std::string states_file;  // empty: no per-step output
  bool classify = false;    // also the rollout verdict of each rollout
};

// The rollouts as CSV, one row per (rollout, step t = 0..H): t, time t dt,
// the true state x_t (columns named as the scene's states), the controls
// u_t applied from x_t (empty at t = H) and the cost of x_t (empty at t = 0:
// an episode's cost sums the post-step states x_1..x_H). States are the
// learner's (the unicycle's 10-entry GP state). A rollout that ended (the
// unicycle fell after T steps) keeps its rows t > T with empty state and
// control cells and the cost of each step from the fall on (1), so that
// the cost column still sums to the episode's cost. Numbers are the
// shortest round-trip text.
std::string RolloutsCsv(const tasks::Scene& scene, const learner::PolicyEvaluation& evaluation) {
  const tasks::SceneDefinition& definition = *scene.definition;
  std::vector<std::string> header = {"rollout", "step", "time_s"};
  for (const std::string& name : definition.LearnerStateNames()) header.push_back(name);
  for (const std::string& name : definition.control_names) header.push_back(name);
  header.push_back("cost");
  std::string csv = io::CsvLine(header) + "\n";
  const int d = scene.state_dim(), f = scene.control_dim();
  for (size_t r = 0; r < evaluation.rollouts.size(); ++r) {
    const tasks::Episode& run = evaluation.rollouts[r];
    const int horizon = static_cast<int>(run.costs.size());
    const int kept = static_cast<int>(run.states.rows()) - 1;  // T: H, or the steps before a fall
    for (int t = 0; t <= horizon; ++t) {
      std::vector<std::string> cells = {std::to_string(r), std::to_string(t),
                                        io::RecordNumberText(t * definition.dt)};
      for (int i = 0; i < d; ++i)
        cells.push_back(t <= kept ? io::RecordNumberText(run.states(t, i)) : "");
      for (int j = 0; j < f; ++j) {
        cells.push_back(t < kept ? io::RecordNumberText(run.forces(t * f + j)) : "");
      }
      cells.push_back(t > 0 ? io::RecordNumberText(run.costs(t - 1)) : "");
      csv += io::CsvLine(cells) + "\n";
    }
  }
  return csv;
}

// The snapshot the flags select (the file's last, or that of
// --snapshot-episode) and its trial options with the flags' overrides
// (--scene, --cost, --noise-k, --seed, --set). Returns the exit code: 0, or
// 2 after a message on stderr.
int LoadPolicy(const EvaluateFlags& flags, std::vector<learner::TrialSnapshot>& snapshots,
               const learner::TrialSnapshot*& snapshot, learner::TrialOptions& options) {
  absl::StatusOr<std::vector<learner::TrialSnapshot>> read =
      io::ReadSnapshotFile(flags.policy_file);
  if (!read.ok()) {
    std::cerr << "evaluate: " << read.status().message() << "\n";
    return 2;
  }
  snapshots = *std::move(read);
  if (snapshots.empty()) {
    std::cerr << "evaluate: " << flags.policy_file << " holds no snapshot\n";
    return 2;
  }
  snapshot = &snapshots.back();
  if (flags.snapshot_episode >= 0) {
    snapshot = nullptr;
    for (const auto& s : snapshots) {
      if (s.episode == flags.snapshot_episode) snapshot = &s;
    }
    if (snapshot == nullptr) {
      std::cerr << "evaluate: " << flags.policy_file << " has no snapshot of episode "
                << flags.snapshot_episode << "\n";
      return 2;
    }
  }
  for (const auto& [key, value] : snapshot->options) {
    const absl::Status status = learner::SetTrialOption(key, value, &options);
    if (!status.ok()) {
      std::cerr << "evaluate: " << flags.policy_file << ": " << status.message() << "\n";
      return 2;
    }
  }
  std::vector<std::pair<std::string, std::string>> overrides;
  for (const auto& [key, value] : {std::pair{"scene", flags.scene}, std::pair{"cost", flags.cost},
                                   std::pair{"noise_k", flags.noise_k},
                                   std::pair{"seed", flags.seed}}) {
    if (!value.empty()) overrides.emplace_back(key, value);
  }
  for (const std::string& set : flags.sets) {
    const size_t equals = set.find('=');
    if (equals == std::string::npos) {
      std::cerr << "evaluate: --set '" << set << "': expected key=value\n";
      return 2;
    }
    overrides.emplace_back(set.substr(0, equals), set.substr(equals + 1));
  }
  for (const auto& [key, value] : overrides) {
    const absl::Status status = learner::SetTrialOption(key, value, &options);
    if (!status.ok()) {
      std::cerr << "evaluate: " << status.message() << "\n";
      return 2;
    }
  }
  return 0;
}

int RunEvaluate(const EvaluateFlags& flags) {
  std::vector<learner::TrialSnapshot> snapshots;
  const learner::TrialSnapshot* snapshot = nullptr;
  learner::TrialOptions options;
  if (const int code = LoadPolicy(flags, snapshots, snapshot, options); code != 0) return code;
  const int episode = flags.episode >= 0 ? flags.episode : snapshot->episode;
  absl::StatusOr<learner::PolicyEvaluation> evaluation =
      learner::EvaluatePolicy(options, snapshot->policy_parameters, episode, flags.rollouts,
                              /*keep_rollouts=*/!flags.states_file.empty() || flags.classify);
  if (!evaluation.ok()) {
    std::cerr << "evaluate: " << evaluation.status().message() << "\n";
    return evaluation.status().code() == absl::StatusCode::kInvalidArgument ? 2 : 1;
  }
  // EvaluatePolicy accepted these options, so the scene builds.
  absl::StatusOr<tasks::Scene> scene = tasks::MakeScene(options.scene);
  if (!scene.ok()) {
    std::cerr << "evaluate: " << scene.status().message() << "\n";
    return 2;
  }
  // The rollout verdict by the options' rule (verdict_distance,
  // verdict_hold_seconds; --set changes them), rollout by rollout: the same
  // streams as the trial's classification of this episode's policy
  // (learner::ClassifyController), so --rollouts verdict_rollouts on a
  // trial's last episode gives the trial's held_fraction.
  std::vector<bool> held;
  learner::RolloutClassification classification;
  if (flags.classify) {
    const int hold_steps = learner::VerdictHoldSteps(options, *scene);  // within 1..horizon
    classification.rollouts = flags.rollouts;
    for (const tasks::Episode& run : evaluation->rollouts) {
      held.push_back(learner::RolloutHeld(*scene, run, options.verdict_distance, hold_steps));
      if (held.back()) ++classification.held;
    }
  }
  if (!flags.states_file.empty()) {
    const absl::Status written =
        io::WriteTextFile(flags.states_file, RolloutsCsv(*scene, *evaluation));
    if (!written.ok()) {
      std::cerr << "evaluate: " << written.message() << "\n";
      return 1;
    }
  }
  if (flags.json) {
    nlohmann::ordered_json out;
    out["policy_file"] = flags.policy_file;
    out["snapshot_episode"] = snapshot->episode;
    out["method"] = estimators::MethodName(options.method);
    out["seed"] = options.seed;
    out["scene"] = options.scene.scene;
    out["cost"] = options.scene.cost;
    out["noise_k"] = options.scene.noise_k;
    out["stream_episode"] = episode;
    out["rollouts"] = flags.rollouts;
    out["mean"] = evaluation->mean;  // round-trip precision
    out["std"] = evaluation->std;
    out["costs"] = evaluation->costs;
    if (flags.classify) {
      out["verdict_distance"] = options.verdict_distance;
      out["verdict_hold_seconds"] = options.verdict_hold_seconds;
      out["held"] = held;
      out["held_fraction"] = classification.held_fraction();
      out["verdict"] = classification.verdict();
    }
    std::cout << out.dump() << "\n";
  } else {
    std::cout << "policy of episode " << snapshot->episode << " (" << estimators::MethodName(options.method) << ", seed "
              << options.seed << ") on " << options.scene.scene << ", cost " << options.scene.cost
              << ", noise_k " << options.scene.noise_k << ": mean cost "
              << absl::StrCat(evaluation->mean) << ", std " << absl::StrCat(evaluation->std)
              << " over " << flags.rollouts << " rollouts\n";
    if (flags.classify) {
      std::cout << "rollout verdict: held in " << classification.held << " of " << flags.rollouts
                << " rollouts (tip within " << options.verdict_distance << " of the goal for the last "
                << options.verdict_hold_seconds << " s): "
                << (classification.verdict() ? "held" : "not held") << "\n";
    }
  }
  return 0;
}

}  // namespace

void AddEvaluateCommand(CLI::App* app, int* exit_code) {
  auto flags = std::make_shared<EvaluateFlags>();
  CLI::App* command = app->add_subcommand(
      "evaluate", "run a saved policy (trial snapshot file) on the real plant");
  command->add_option("--policy", flags->policy_file,
                      "trial snapshot file (totalgrad job artifacts, trial --snapshot-file)")
      ->required();
  command->add_option("--snapshot-episode", flags->snapshot_episode,
                      "which snapshot of the file (default: the last)");
  command->add_option("--rollouts", flags->rollouts, "real episodes to run")
      ->required()
      ->check(CLI::Range(1, 1000000));
  command->add_option("--scene", flags->scene, "another scene than the trial's");
  command->add_option("--cost", flags->cost, "another cost than the trial's");
  command->add_option("--noise-k", flags->noise_k, "another noise level than the trial's");
  command->add_option("--seed", flags->seed, "another seed for the rollouts' draws");
  command->add_option("--episode", flags->episode,
                      "draw as the trial's evaluation of this episode (default: the snapshot's)");
  command->add_option("--set", flags->sets, "any other trial option, key=value (repeatable)");
  command->add_flag("--json", flags->json, "one JSON object (numbers with round-trip precision)");
  command->add_option("--states", flags->states_file,
                      "also write every rollout step by step to this CSV file (rollout, step, "
                      "time_s, the true states, the controls applied, the step's cost)");
  command->add_flag("--classify", flags->classify,
                    "also classify each rollout by the rollout verdict's rule (trial options "
                    "verdict_distance, verdict_hold_seconds: --set to change) and print the "
                    "fraction held");
  command->callback([flags, exit_code] { *exit_code = RunEvaluate(*flags); });
}

}  // namespace totalgrad::cli
