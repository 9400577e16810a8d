// `totalgrad evaluate`: --states writes every rollout step by step, and what
// it writes is the evaluation it reports (the per-step costs sum to each
// rollout's cost; asking for the states changes no number).
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "absl/strings/str_split.h"
#include "tests/client/core_commands/run_command.h"
#include "tests/testutil/testutil.h"

namespace totalgrad::cli {
namespace evaluate_command_test {

using testing_support::CommandRun;
using testing_support::RunCommand;

std::string Dir(const std::string& name) { return testing_support::FreshDir(name); }

std::vector<std::vector<std::string>> ReadCsv(const std::string& path) {
  std::ifstream in(path);
  std::vector<std::vector<std::string>> rows;
  std::string line;
  while (std::getline(in, line)) rows.push_back(absl::StrSplit(line, ','));
  return rows;
}

// A tiny double-pendulum trial (two torques, |u| <= 2) and its final policy.
std::string TrainTinyPolicy(const std::string& dir) {
  const std::string snapshots = dir + "/snapshots.json";
  const CommandRun trial = RunCommand(
      {"trial", "--scene", "double-pendulum", "--episodes", "1", "--policy-steps", "2",
       "--particles", "8", "--horizon", "7", "--basis-functions", "5", "--eval-rollouts", "1",
       "--gp-iterations", "10", "--seed", "3", "--snapshot-episodes", "1", "--snapshot-file",
       snapshots});
  EXPECT_EQ(trial.exit_code, 0) << trial.err;
  return snapshots;
}

TEST(EvaluateCommand, StatesFileHoldsEveryStepOfTheReportedRollouts) {
  const std::string dir = Dir("evaluate_states");
  const std::string policy = TrainTinyPolicy(dir);
  const std::string states = dir + "/states.csv";
  const CommandRun with_states = RunCommand(
      {"evaluate", "--policy", policy, "--rollouts", "3", "--json", "--states", states});
  ASSERT_EQ(with_states.exit_code, 0) << with_states.err;
  const CommandRun without = RunCommand({"evaluate", "--policy", policy, "--rollouts", "3", "--json"});
  ASSERT_EQ(without.exit_code, 0) << without.err;
  const nlohmann::json report = nlohmann::json::parse(with_states.out);
  EXPECT_EQ(report, nlohmann::json::parse(without.out));  // same numbers, bit for bit

  const std::vector<std::vector<std::string>> rows = ReadCsv(states);
  const int horizon = 7, state_dim = 4, controls = 2;
  ASSERT_EQ(rows.size(), 1u + 3u * (horizon + 1));
  EXPECT_EQ(rows[0], (std::vector<std::string>{"rollout", "step", "time_s", "dtheta1", "dtheta2",
                                               "theta1", "theta2", "torque1", "torque2", "cost"}));
  for (int r = 0; r < 3; ++r) {
    double cost_sum = 0;
    for (int t = 0; t <= horizon; ++t) {
      const std::vector<std::string>& row = rows[1 + r * (horizon + 1) + t];
      ASSERT_EQ(row.size(), 3u + state_dim + controls + 1);
      EXPECT_EQ(row[0], std::to_string(r));
      EXPECT_EQ(row[1], std::to_string(t));
      EXPECT_DOUBLE_EQ(std::stod(row[2]), 0.1 * t);  // the double pendulum's dt
      for (int i = 0; i < state_dim; ++i) EXPECT_TRUE(std::isfinite(std::stod(row[3 + i])));
      for (int j = 0; j < controls; ++j) {
        const std::string& u = row[3 + state_dim + j];
        if (t == horizon) {
          EXPECT_EQ(u, "") << "no control is applied from the last state";
        } else {
          EXPECT_LE(std::abs(std::stod(u)), 2.0) << "the saturated torque";
        }
      }
      const std::string& cost = row.back();
      if (t == 0) {
        EXPECT_EQ(cost, "") << "an episode's cost is of the post-step states";
      } else {
        cost_sum += std::stod(cost);
      }
    }
    // Shortest round-trip numbers summed in step order: the rollout's cost.
    EXPECT_EQ(cost_sum, report.at("costs").at(r).get<double>()) << "rollout " << r;
  }
}

// The unicycle: the rows hold the learner's 10-entry state under its names,
// and a rollout that fell keeps H + 1 rows: its kept steps, then empty
// state and control cells with the cost 1 of each step from the fall on,
// so the cost column still sums to the rollout's cost. (The initial policy
// of docs/results/scenes/unicycle_unlearned_seed1 falls within a second.)
TEST(EvaluateCommand, AUnicycleThatFellKeepsItsRowsAndItsCost) {
  const std::string dir = Dir("evaluate_unicycle");
  const std::string policy =
      std::string(TOTALGRAD_SOURCE_DIR) + "/docs/results/scenes/unicycle_unlearned_seed1.snapshots.json";
  const std::string states = dir + "/states.csv";
  const CommandRun run = RunCommand(
      {"evaluate", "--policy", policy, "--rollouts", "2", "--json", "--states", states});
  ASSERT_EQ(run.exit_code, 0) << run.err;
  const nlohmann::json report = nlohmann::json::parse(run.out);
  const std::vector<std::vector<std::string>> rows = ReadCsv(states);
  const int horizon = 67, state_dim = 10, controls = 2;
  ASSERT_EQ(rows.size(), 1u + 2u * (horizon + 1));
  EXPECT_EQ(rows[0], (std::vector<std::string>{"rollout", "step", "time_s", "dtheta", "dphi",
                                               "dpsiw", "dpsif", "dpsit", "xc", "yc", "theta",
                                               "phi", "psif", "turntable", "wheel", "cost"}));
  for (int r = 0; r < 2; ++r) {
    double cost_sum = 0;
    int kept = -1;
    for (int t = 0; t <= horizon; ++t) {
      const std::vector<std::string>& row = rows[1 + r * (horizon + 1) + t];
      ASSERT_EQ(row.size(), 3u + state_dim + controls + 1);
      if (row[3].empty()) {
        if (kept < 0) kept = t - 1;
        EXPECT_EQ(row.back(), "1") << "a step after the fall costs the maximum";
      } else {
        EXPECT_LT(kept, 0) << "no state after the fall";
        for (int i = 0; i < state_dim; ++i) EXPECT_TRUE(std::isfinite(std::stod(row[3 + i])));
      }
      if (t > 0) cost_sum += std::stod(row.back());
    }
    EXPECT_GT(kept, 0) << "rollout " << r << " fell";
    EXPECT_LT(kept, 20) << "rollout " << r << " fell within 3 s";
    EXPECT_EQ(cost_sum, report.at("costs").at(r).get<double>()) << "rollout " << r;
  }
}

TEST(EvaluateCommand, UnwritableStatesFileIsNamed) {
  const std::string dir = Dir("evaluate_states_unwritable");
  const std::string policy = TrainTinyPolicy(dir);
  const std::string states = dir + "/no/such/dir/states.csv";
  const CommandRun run =
      RunCommand({"evaluate", "--policy", policy, "--rollouts", "2", "--states", states});
  EXPECT_EQ(run.exit_code, 1);
  EXPECT_NE(run.err.find(states), std::string::npos) << run.err;
}

}  // namespace evaluate_command_test
}  // namespace totalgrad::cli
