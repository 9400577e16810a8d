// io/trajectory_json.h: the view of a recorded trajectory that the CLI's
// `job trajectory` and the dashboard print, from a real (tiny) trial's last
// checkpoint: names from the scene catalog, rows t = 0..H with the
// prediction's columns, the goal distance of every state, the cart-pole's
// geometry, and what is not there refused by name.
#include "io/trajectory_json.h"

#include <gtest/gtest.h>

#include <cmath>
#include <string>
#include <utility>
#include <vector>

#include "core/learner/trial.h"
#include "core/tasks/scene.h"

namespace totalgrad::io {
namespace trajectory_json_test {

learner::TrialCheckpoint TinyTrialCheckpoint() {
  learner::TrialOptions o;
  const std::vector<std::pair<std::string, std::string>> pairs = {
      {"method", "RP"},         {"episodes", "2"},        {"policy_steps", "3"},
      {"particles", "8"},       {"eval_rollouts", "2"},   {"horizon", "10"},
      {"basis_functions", "8"}, {"gp_iterations", "15"},  {"predicted_cost_particles", "20"},
      {"seed", "4"},            {"verdict_rollouts", "3"}, {"verdict_hold_seconds", "0.3"}};
  for (const auto& [k, v] : pairs) EXPECT_TRUE(learner::SetTrialOption(k, v, &o).ok()) << k;
  class Keep final : public learner::TrialObserver {
   public:
    void OnEpisode(const learner::EpisodeResult&) override {}
    bool WantsCheckpoints() override { return true; }
    void OnCheckpoint(const learner::TrialCheckpoint& c) override { last = c; }
    learner::TrialCheckpoint last;
  } keep;
  EXPECT_TRUE(learner::RunTrial(o, &keep).ok());
  return keep.last;
}

TEST(TrajectoryJsonTest, ViewsAnEpisodeWithItsPrediction) {
  const learner::TrialCheckpoint checkpoint = TinyTrialCheckpoint();
  absl::StatusOr<TrajectoryView> view = ViewTrajectory(checkpoint, 1, -1);
  ASSERT_TRUE(view.ok()) << view.status();
  EXPECT_EQ(view->scene, "cartpole-swingup");
  EXPECT_EQ(view->dt, 0.1);
  EXPECT_EQ(view->state_names, (std::vector<std::string>{"s", "beta", "s_dot", "beta_dot"}));
  EXPECT_EQ(view->control_names, std::vector<std::string>{"force"});
  EXPECT_EQ(view->verdict_hold_steps, 3);
  EXPECT_EQ(view->cart_index, 0);
  ASSERT_EQ(view->links.size(), 1u);
  EXPECT_EQ(view->links[0], (std::pair<int, double>{1, 0.5}));
  // The goal distance of x_0 by hand: the tip at (s + l sin b, -l cos b)
  // against the upright tip (0, l).
  const auto x0 = checkpoint.episodes[1].trajectories.real.states.row(0);
  const double l = 0.5, tip_x = x0(0) + l * std::sin(x0(1)), tip_y = -l * std::cos(x0(1));
  EXPECT_NEAR(view->goal_distance[0], std::hypot(tip_x, tip_y - l), 1e-12);

  const TrajectoryTable table = TrajectoryRows(*view);
  EXPECT_EQ(table.columns,
            (std::vector<std::string>{"t", "time", "s", "beta", "s_dot", "beta_dot", "force",
                                      "mean_s", "mean_beta", "mean_s_dot", "mean_beta_dot",
                                      "std_s", "std_beta", "std_s_dot", "std_beta_dot"}));
  ASSERT_EQ(table.rows.size(), 11u);
  EXPECT_EQ(table.rows[10][1], 10 * 0.1);
  EXPECT_EQ(table.rows[3][3], checkpoint.episodes[1].trajectories.real.states(3, 1));
  EXPECT_TRUE(std::isnan(table.rows[10][6]));  // no control after the last state
  EXPECT_EQ(table.rows[9][6], checkpoint.episodes[1].trajectories.real.controls(9, 0));
  EXPECT_EQ(table.rows[4][11], checkpoint.episodes[1].trajectories.predicted_std(4, 0));

  const nlohmann::ordered_json json = TrajectoryToJson(*view);
  EXPECT_EQ(json["states"].size(), 11u);
  EXPECT_EQ(json["controls"].size(), 10u);
  EXPECT_EQ(json["predicted_mean"].size(), 11u);
  EXPECT_EQ(json["verdict_rollouts"], 0);
  EXPECT_EQ(json["geometry"]["cart"], 0);
  EXPECT_EQ(json["geometry"]["links"][0]["length"], 0.5);
  EXPECT_FALSE(json.contains("rollout"));
}

TEST(TrajectoryJsonTest, ViewsAVerdictRolloutAndTheRandomEpisode) {
  const learner::TrialCheckpoint checkpoint = TinyTrialCheckpoint();
  absl::StatusOr<TrajectoryView> rollout = ViewTrajectory(checkpoint, 2, 2);
  ASSERT_TRUE(rollout.ok()) << rollout.status();
  EXPECT_EQ(rollout->verdict_rollouts, 3);
  EXPECT_EQ(rollout->shown, &checkpoint.episodes[2].trajectories.verdict_rollouts[2]);
  EXPECT_EQ(TrajectoryToJson(*rollout)["rollout"], 2);
  absl::StatusOr<TrajectoryView> random = ViewTrajectory(checkpoint, 0, -1);
  ASSERT_TRUE(random.ok()) << random.status();
  const TrajectoryTable table = TrajectoryRows(*random);
  EXPECT_EQ(table.columns.size(), 7u);  // no prediction for the random episode
}

TEST(TrajectoryJsonTest, RefusesWhatIsNotThere) {
  learner::TrialCheckpoint checkpoint = TinyTrialCheckpoint();
  auto says = [&](int episode, int rollout, const std::string& text) {
    absl::StatusOr<TrajectoryView> view = ViewTrajectory(checkpoint, episode, rollout);
    ASSERT_FALSE(view.ok());
    EXPECT_EQ(view.status().code(), absl::StatusCode::kNotFound);
    EXPECT_NE(view.status().message().find(text), std::string::npos) << view.status();
  };
  says(3, -1, "episode 3 is not recorded: the trial holds episodes 0..2");
  says(2, 3, "episode 2 holds 3 verdict rollouts (0..2); rollout 3 is not one of them");
  says(1, 0, "only a trial's last episode holds them");
  checkpoint.episodes[1].trajectories = {};
  says(1, -1, "episode 1 was recorded without trajectories");
}

}  // namespace trajectory_json_test
}  // namespace totalgrad::io
