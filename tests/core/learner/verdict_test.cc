// The rollout verdict (issue 25): the goal distance by hand, the per-rollout
// rule on hand-made rollouts, ClassifyController against its rule, the trial
// classifying only its final policy with the evaluation's own streams, and a
// real swing-up policy that holds, and the same policy dropping the pole
// after it swung up, which must not.
#include <gtest/gtest.h>

#include <cmath>
#include <numbers>
#include <string>
#include <utility>
#include <vector>

#include "core/learner/evaluation.h"
#include "core/learner/problem_builder.h"
#include "core/learner/trial.h"
#include "core/learner/trial_options.h"
#include "core/gaussian/angle_features.h"
#include "core/policy/rbf_policy.h"
#include "core/tasks/scene.h"

namespace totalgrad::learner {
namespace verdict_test {

constexpr double kPi = std::numbers::pi;

tasks::Scene CartPoleScene(const std::string& scene = "cartpole-swingup") {
  tasks::SceneOptions options;
  options.scene = scene;
  options.cost = "tip";
  absl::StatusOr<tasks::Scene> made = tasks::MakeScene(options);
  EXPECT_TRUE(made.ok()) << made.status();
  return *made;
}

Vector State4(double s, double beta, double s_dot = 0, double beta_dot = 0) {
  Vector x(4);
  x << s, beta, s_dot, beta_dot;
  return x;
}

TEST(GoalDistance, IsTheTipsDistanceFromTheUprightTipOnTheCartPole) {
  const tasks::Scene scene = CartPoleScene();
  // Upright above the target: 0. Hanging: the tip is 2 l = 1 m below.
  EXPECT_NEAR(tasks::GoalDistance(scene, State4(0, kPi)), 0.0, 1e-15);
  EXPECT_NEAR(tasks::GoalDistance(scene, State4(0, 0)), 1.0, 1e-15);
  // Upright, cart 0.3 m off: 0.3. Velocities do not count.
  EXPECT_NEAR(tasks::GoalDistance(scene, State4(0.3, kPi, 2.0, -5.0)), 0.3, 1e-15);
  // Horizontal pole (beta = pi/2) on a cart at s = -0.5: the tip at (0, 0),
  // the goal at (0, 0.5).
  EXPECT_NEAR(tasks::GoalDistance(scene, State4(-0.5, kPi / 2)), 0.5, 1e-15);
  // A full turn more is the same place.
  EXPECT_NEAR(tasks::GoalDistance(scene, State4(0.1, 3 * kPi)), 0.1, 1e-14);
  // The plant's own pole length: 1 m hanging is 2 m below the upright tip.
  tasks::SceneOptions longer;
  longer.scene = "cartpole-swingup";
  longer.plant.pole_length = 1.0;
  absl::StatusOr<tasks::Scene> made = tasks::MakeScene(longer);
  ASSERT_TRUE(made.ok());
  EXPECT_NEAR(tasks::GoalDistance(*made, State4(0, 0)), 2.0, 1e-15);
}

TEST(GoalDistance, IsThePendulumTipsOnThePendulum) {
  tasks::SceneOptions options;
  options.scene = "pendulum";
  absl::StatusOr<tasks::Scene> scene = tasks::MakeScene(options);
  ASSERT_TRUE(scene.ok()) << scene.status();
  // State [dtheta, theta], l = 1 m, theta = pi upright: hanging is 2 m away,
  // horizontal sqrt(2).
  Vector hanging(2), horizontal(2);
  hanging << 3.0, 0.0;
  horizontal << 0.0, kPi / 2;
  EXPECT_NEAR(tasks::GoalDistance(*scene, hanging), 2.0, 1e-14);
  EXPECT_NEAR(tasks::GoalDistance(*scene, horizontal), std::sqrt(2.0), 1e-14);
}

// A rollout of horizon 30 whose pole angle at step t is beta(t), the cart at 0.
tasks::Episode Rollout(const std::function<double(int)>& beta) {
  tasks::Episode run;
  run.states.resize(31, 4);
  for (int t = 0; t <= 30; ++t) run.states.row(t) = State4(0, beta(t)).transpose();
  return run;
}

TEST(RolloutHeld, LooksOnlyAtTheLastHoldSteps) {
  const tasks::Scene scene = CartPoleScene();
  // Up from step 10 on: tip 0 from x_10.
  const tasks::Episode up_early = Rollout([](int t) { return t < 10 ? 0.0 : kPi; });
  EXPECT_TRUE(RolloutHeld(scene, up_early, 0.2, 10));
  EXPECT_TRUE(RolloutHeld(scene, up_early, 0.2, 21));  // x_10..x_30
  EXPECT_FALSE(RolloutHeld(scene, up_early, 0.2, 22));  // x_9 hangs
  // Swung up, then dropped at the very end: x_30 hangs; not held however
  // long it was up.
  const tasks::Episode dropped = Rollout([](int t) { return t >= 5 && t < 30 ? kPi : 0.0; });
  EXPECT_FALSE(RolloutHeld(scene, dropped, 0.2, 10));
  EXPECT_FALSE(RolloutHeld(scene, dropped, 0.2, 1));
  // At most the distance is held, beyond it is not: a pole 0.1 rad off
  // upright has its tip l |sin 0.1| across and l (1 - cos 0.1) down.
  const double off = 0.1;
  const double d = std::hypot(0.5 * std::sin(kPi + off), 0.5 * (std::cos(kPi + off) + 1));
  const tasks::Episode leaning = Rollout([&](int) { return kPi + off; });
  EXPECT_TRUE(RolloutHeld(scene, leaning, d + 1e-12, 30));
  EXPECT_FALSE(RolloutHeld(scene, leaning, d - 1e-12, 30));
  // A NaN state is never held.
  tasks::Episode broken = up_early;
  broken.states(30, 1) = std::nan("");
  EXPECT_FALSE(RolloutHeld(scene, broken, 0.2, 10));
}

TEST(ClassifyController, CountsRolloutsByTheRuleAndRefusesBadRules) {
  tasks::Scene scene = CartPoleScene();
  // No force: the pole hangs; every rollout is far from the goal.
  const tasks::MultiController idle = [](const Vector&) { return Vector::Zero(1).eval(); };
  absl::StatusOr<RolloutClassification> none = ClassifyController(scene, idle, 3, 7, 20, 0.2, 10);
  ASSERT_TRUE(none.ok()) << none.status();
  EXPECT_EQ(none->rollouts, 20);
  EXPECT_EQ(none->held, 0);
  EXPECT_FALSE(none->verdict());
  // Within 2 m of the goal: everything is.
  absl::StatusOr<RolloutClassification> all = ClassifyController(scene, idle, 3, 7, 20, 2.0, 10);
  ASSERT_TRUE(all.ok());
  EXPECT_EQ(all->held, 20);
  EXPECT_EQ(all->held_fraction(), 1.0);
  EXPECT_TRUE(all->verdict());
  // Exactly half held is a held verdict; fewer is not.
  RolloutClassification half;
  half.rollouts = 10;
  half.held = 5;
  EXPECT_TRUE(half.verdict());
  half.held = 4;
  EXPECT_FALSE(half.verdict());
  EXPECT_EQ(ClassifyController(scene, idle, 3, 7, 0, 0.2, 10).status().code(),
            absl::StatusCode::kInvalidArgument);
  EXPECT_EQ(ClassifyController(scene, idle, 3, 7, 5, 0.0, 10).status().code(),
            absl::StatusCode::kInvalidArgument);
  EXPECT_EQ(ClassifyController(scene, idle, 3, 7, 5, 0.2, 31).status().code(),
            absl::StatusCode::kInvalidArgument);
}

TEST(VerdictOptions, AreValidatedAndAbsentFromOldPairsMeansNone) {
  TrialOptions options;
  EXPECT_EQ(options.verdict_rollouts, 100);
  EXPECT_TRUE(options.Validate().ok());
  // 1 s at dt = 0.1 s is 10 steps.
  absl::StatusOr<tasks::Scene> scene = tasks::MakeScene(options.scene);
  ASSERT_TRUE(scene.ok());
  EXPECT_EQ(VerdictHoldSteps(options, *scene), 10);
  // Longer than the episode: the whole episode; shorter than a step: the last step.
  TrialOptions longer = options;
  longer.verdict_hold_seconds = 3.5;
  EXPECT_TRUE(longer.Validate().ok());
  EXPECT_EQ(VerdictHoldSteps(longer, *scene), 30);
  longer.verdict_hold_seconds = 0.01;
  EXPECT_EQ(VerdictHoldSteps(longer, *scene), 1);
  TrialOptions bad = options;
  bad.verdict_hold_seconds = 0;
  EXPECT_NE(bad.Validate().message().find("verdict_hold_seconds"), std::string::npos);
  bad = options;
  bad.verdict_distance = -1;
  EXPECT_NE(bad.Validate().message().find("verdict_distance"), std::string::npos);
  bad = options;
  bad.verdict_rollouts = -1;
  EXPECT_NE(bad.Validate().message().find("verdict_rollouts"), std::string::npos);
  // Pairs stored before the key existed describe trials that classified none.
  absl::StatusOr<TrialOptions> stored = TrialOptionsFromStoredPairs({{"seed", "3"}});
  ASSERT_TRUE(stored.ok());
  EXPECT_EQ(stored->verdict_rollouts, 0);
  absl::StatusOr<TrialOptions> fresh = TrialOptionsFromPairs({{"seed", "3"}});
  ASSERT_TRUE(fresh.ok());
  EXPECT_EQ(fresh->verdict_rollouts, 100);
}

// A real swing-up policy (PILCO's, tests/core/learner/testdata) holds the
// pole in most rollouts; the same policy that, 2 s into the episode, stops
// balancing and pushes the cart with full force swings the pole up and then
// drops it: no rollout of it may be held, although it spent two thirds of
// the episode on the same path as the policy that holds.
TEST(RolloutVerdict, APolicyThatSwingsUpAndThenDropsThePoleIsNotHeld) {
  TrialOptions options;
  ASSERT_TRUE(SetTrialOption("method", "PILCO", &options).ok());
  ASSERT_TRUE(SetTrialOption("cost", "tip", &options).ok());
  ASSERT_TRUE(SetTrialOption("seed", "10", &options).ok());
  absl::StatusOr<tasks::Scene> scene = tasks::MakeScene(options.scene);
  ASSERT_TRUE(scene.ok());
  const std::vector<double> parameters = {
#include "tests/core/learner/testdata/pilco_swingup_policy.inc"
  };
  const std::vector<int> angles = FeatureAngles(options, *scene);
  TrialPolicy policy(policy::PolicyClass::kRbf, options.basis_functions,
                     gaussian::FeatureDim(scene->state_dim(), angles), scene->max_control);
  ASSERT_EQ(policy.num_parameters(), static_cast<int>(parameters.size()));
  policy.set_parameters(Eigen::Map<const Vector>(parameters.data(), parameters.size()));
  const tasks::MultiController swing_up = FeaturePolicyController(&policy, angles);
  // The controller is called once per step, rollout after rollout.
  int step = 0;
  const tasks::MultiController drop_after_2s = [&](const Vector& observation) {
    const int t = step++ % scene->horizon;
    return t < 20 ? swing_up(observation) : Vector::Constant(1, scene->max_control(0)).eval();
  };
  const int hold_steps = VerdictHoldSteps(options, *scene);
  absl::StatusOr<RolloutClassification> holds =
      ClassifyController(*scene, swing_up, 10, 15, 100, options.verdict_distance, hold_steps);
  ASSERT_TRUE(holds.ok()) << holds.status();
  EXPECT_GE(holds->held, 60);
  EXPECT_TRUE(holds->verdict());
  step = 0;
  absl::StatusOr<RolloutClassification> drops =
      ClassifyController(*scene, drop_after_2s, 10, 15, 100, options.verdict_distance, hold_steps);
  ASSERT_TRUE(drops.ok()) << drops.status();
  EXPECT_EQ(drops->held, 0);
  EXPECT_FALSE(drops->verdict());
}

TrialOptions Tiny(const std::string& method, const std::vector<std::pair<std::string, std::string>>& extra = {}) {
  TrialOptions o;
  std::vector<std::pair<std::string, std::string>> pairs = {
      {"method", method},     {"episodes", "2"},       {"policy_steps", "3"},
      {"particles", "8"},     {"eval_rollouts", "4"},  {"horizon", "12"},
      {"basis_functions", "8"}, {"gp_iterations", "10"}, {"predicted_cost_particles", "20"},
      {"seed", "11"},         {"verdict_rollouts", "9"}, {"verdict_distance", "0.9"}};
  pairs.insert(pairs.end(), extra.begin(), extra.end());
  for (const auto& [k, v] : pairs) EXPECT_TRUE(SetTrialOption(k, v, &o).ok()) << k << "=" << v;
  return o;
}

TEST(TrialVerdict, OnlyTheLastEpisodeIsClassifiedAsClassifyPolicySays) {
  for (const std::string method : {"RP", "PILCO"}) {
    SCOPED_TRACE(method);
    const TrialOptions options = Tiny(method);
    absl::StatusOr<TrialSummary> summary = RunTrial(options, nullptr);
    ASSERT_TRUE(summary.ok()) << summary.status();
    ASSERT_EQ(summary->episodes.size(), 3u);
    EXPECT_TRUE(std::isnan(summary->episodes[0].held_fraction));
    EXPECT_TRUE(std::isnan(summary->episodes[1].held_fraction));
    const EpisodeResult& last = summary->episodes[2];
    ASSERT_FALSE(std::isnan(last.held_fraction));
    // A multiple of 1/9, and what classifying the final policy again gives.
    EXPECT_EQ(last.held_fraction * 9, std::round(last.held_fraction * 9));
    absl::StatusOr<RolloutClassification> again = ClassifyPolicy(options, last.policy_parameters, 2);
    ASSERT_TRUE(again.ok()) << again.status();
    EXPECT_EQ(again->held_fraction(), last.held_fraction);
    // A rule no rollout meets, and one every rollout meets.
    TrialOptions strict = options;
    strict.verdict_distance = 1e-9;
    absl::StatusOr<RolloutClassification> none = ClassifyPolicy(strict, last.policy_parameters, 2);
    ASSERT_TRUE(none.ok());
    EXPECT_EQ(none->held, 0);
    TrialOptions loose = options;
    loose.verdict_distance = 1e3;
    absl::StatusOr<RolloutClassification> all = ClassifyPolicy(loose, last.policy_parameters, 2);
    ASSERT_TRUE(all.ok());
    EXPECT_EQ(all->held, 9);
  }
}

TEST(TrialVerdict, ChangesNoOtherNumberOfTheTrial) {
  const TrialOptions with = Tiny("RP");
  TrialOptions without = with;
  without.verdict_rollouts = 0;
  absl::StatusOr<TrialSummary> a = RunTrial(with, nullptr);
  absl::StatusOr<TrialSummary> b = RunTrial(without, nullptr);
  ASSERT_TRUE(a.ok() && b.ok());
  ASSERT_EQ(a->episodes.size(), b->episodes.size());
  for (size_t e = 0; e < a->episodes.size(); ++e) {
    EXPECT_EQ(a->episodes[e].real_cost, b->episodes[e].real_cost);
    if (e > 0) {
      EXPECT_EQ(a->episodes[e].eval_cost_mean, b->episodes[e].eval_cost_mean);
    }
    EXPECT_EQ(a->episodes[e].policy_parameters, b->episodes[e].policy_parameters);
  }
  EXPECT_TRUE(std::isnan(b->episodes.back().held_fraction));
  EXPECT_FALSE(std::isnan(a->episodes.back().held_fraction));
}

}  // namespace verdict_test
}  // namespace totalgrad::learner
