// The scene catalog: consistent shapes and index sets for every scene, PILCO's
// numbers where the notes give them, and the augmented state.
#include "core/tasks/scene_catalog.h"

#include <gtest/gtest.h>

#include <Eigen/Eigenvalues>
#include <algorithm>

#include <cmath>
#include <limits>
#include <numbers>
#include <random>
#include <set>

#include "core/common/rng.h"
#include "core/tasks/scene.h"

namespace totalgrad::tasks {
namespace scene_catalog_test {

bool StrictlyIncreasingBelow(const std::vector<int>& v, int bound) {
  for (size_t i = 0; i < v.size(); ++i) {
    if (v[i] < 0 || v[i] >= bound) return false;
    if (i > 0 && v[i] <= v[i - 1]) return false;
  }
  return true;
}

TEST(SceneCatalogTest, EveryDefinitionIsConsistent) {
  std::set<std::string> names;
  for (const SceneDefinition& s : SceneCatalog()) {
    SCOPED_TRACE(s.name);
    EXPECT_TRUE(names.insert(s.name).second);
    const int d = s.state_dim(), f = s.control_dim(), z = s.augmented_dim();
    const auto plant = MakePlant(s);
    EXPECT_EQ(plant->state_dim(), d);
    EXPECT_EQ(plant->control_dim(), f);
    EXPECT_EQ(static_cast<int>(s.state_names.size()), d);
    EXPECT_EQ(static_cast<int>(s.state_units.size()), d);
    EXPECT_EQ(static_cast<int>(s.control_names.size()), f);
    for (const Vector* v : {&s.start_std, &s.measurement_noise_std, &s.target})
      EXPECT_EQ(v->size(), d);
    EXPECT_TRUE((s.max_control.array() > 0).all());
    EXPECT_TRUE(StrictlyIncreasingBelow(s.angle_indices, d));
    EXPECT_TRUE(StrictlyIncreasingBelow(s.dynamics_inputs, z));
    EXPECT_TRUE(StrictlyIncreasingBelow(s.policy_inputs, z));
    // The GP and the policy never see a raw angle, only its sin and cos.
    for (int a : s.angle_indices) {
      EXPECT_EQ(std::count(s.dynamics_inputs.begin(), s.dynamics_inputs.end(), a), 0);
      EXPECT_EQ(std::count(s.policy_inputs.begin(), s.policy_inputs.end(), a), 0);
    }
    if (s.cost_kind == "unicycle") {
      EXPECT_TRUE(UnicycleCost(s.unicycle_cost).ok());
    } else {
      EXPECT_EQ(s.cost_kind, "saturating");
      EXPECT_EQ(s.angle_cost_q.size(), d);
      EXPECT_EQ(s.saturating_cost.q.rows(), z);
      EXPECT_EQ(s.saturating_cost.q.cols(), z);
      EXPECT_TRUE(s.saturating_cost.q.isApprox(s.saturating_cost.q.transpose()));
      EXPECT_GE(Eigen::SelfAdjointEigenSolver<Matrix>(s.saturating_cost.q).eigenvalues().minCoeff(),
                -1e-12);
      EXPECT_FALSE(s.saturating_cost.widths.empty());
    }
    EXPECT_TRUE(s.policy_class == "rbf" || s.policy_class == "linear") << s.policy_class;
    EXPECT_GT(s.horizon, 0);
    EXPECT_GT(s.dt, 0);
    EXPECT_FALSE(s.source.empty());
    EXPECT_GT(PeakTrialBytes(s, 300), 0);
  }
  EXPECT_EQ(SceneNames().size(), 7u);
}

// PILCO's unicycle settings (settings_unicycle.m at a0b48b7, as issue 30
// quotes them), and its trials refused with the reason until they exist.
TEST(SceneCatalogTest, UnicycleSettingsAndItsLearnerState) {
  const SceneDefinition* unicycle = FindSceneDefinition("unicycle");
  ASSERT_NE(unicycle, nullptr);
  EXPECT_EQ(unicycle->plant, PlantKind::kUnicycle);
  EXPECT_EQ(unicycle->dt, 0.15);
  EXPECT_EQ(unicycle->horizon, 67);
  EXPECT_EQ(unicycle->max_control, (Vector(2) << 10.0, 50.0).finished());
  EXPECT_EQ(unicycle->start_std(5), 0.1);
  EXPECT_EQ(unicycle->start_std(0), 0.02);
  EXPECT_EQ(unicycle->measurement_noise_std(4), 0.01);
  EXPECT_EQ(unicycle->measurement_noise_std(5), 0.003);
  EXPECT_EQ(unicycle->learned_episodes, 40);
  EXPECT_EQ(unicycle->evaluations_per_line_search, 20);
  EXPECT_EQ(unicycle->policy_class, "linear");
  EXPECT_EQ(unicycle->unicycle_cost.rod_length, 0.81);
  EXPECT_TRUE(unicycle->trials_unavailable.empty());
  EXPECT_FALSE(unicycle->studies_unavailable.empty());
  // The index sets as settings_unicycle.m gives them (1-based there).
  const FullStateIndexSets& sets = unicycle->full_state;
  const auto minus_one = [](std::vector<int> v) {
    for (int& i : v) --i;
    return v;
  };
  EXPECT_EQ(sets.integrated, minus_one({5, 6, 7, 8, 9, 10, 11, 14, 15, 16, 17, 18}));
  EXPECT_EQ(sets.augmented, minus_one({1, 2, 3, 4, 12, 13}));
  EXPECT_EQ(sets.predicted, minus_one({5, 6, 7, 8, 9, 12, 13, 14, 15, 17}));
  EXPECT_EQ(sets.dynamics_inputs, minus_one({1, 2, 3, 4, 5, 6, 7, 8, 10}));
  EXPECT_EQ(sets.policy_inputs, minus_one({1, 2, 3, 4, 5, 6, 7, 8, 9, 10}));
  // integrated, augmented and controls partition the 20 entries; the
  // integrated ones are the plant's state by name, in its order.
  std::vector<int> all = sets.integrated;
  all.insert(all.end(), sets.augmented.begin(), sets.augmented.end());
  all.insert(all.end(), sets.controls.begin(), sets.controls.end());
  std::sort(all.begin(), all.end());
  std::vector<int> every(20);
  for (int i = 0; i < 20; ++i) every[i] = i;
  EXPECT_EQ(all, every);
  ASSERT_EQ(sets.names.size(), 20u);
  for (size_t k = 0; k < sets.integrated.size(); ++k) {
    EXPECT_EQ(sets.names[sets.integrated[k]], unicycle->state_names[k]);
  }
  // The data and the code agree: a full state assembled from a random ODE
  // state (the plant's entries, UnicycleAugmentedEntries, the torques), read
  // at `predicted`, is UnicycleGpState.
  std::mt19937_64 rng(5);
  std::normal_distribution<double> normal;
  Vector ode(12);
  for (int i = 0; i < 12; ++i) ode(i) = normal(rng);
  const Vector augmented = UnicycleAugmentedEntries(ode, unicycle->unicycle.wheel_radius);
  Vector full = Vector::Constant(20, std::numeric_limits<double>::quiet_NaN());
  for (int k = 0; k < 12; ++k) full(sets.integrated[k]) = ode(k);
  for (int k = 0; k < 6; ++k) full(sets.augmented[k]) = augmented(k);
  full(sets.controls[0]) = 1.5;
  full(sets.controls[1]) = -2.5;
  const Vector gp_state = UnicycleGpState(ode, unicycle->unicycle.wheel_radius);
  ASSERT_EQ(gp_state.size(), static_cast<Eigen::Index>(sets.predicted.size()));
  for (size_t k = 0; k < sets.predicted.size(); ++k) {
    EXPECT_EQ(full(sets.predicted[k]), gp_state(k)) << sets.names[sets.predicted[k]];
  }
  // The learner's index sets are the full state's, read in `predicted`.
  EXPECT_EQ(unicycle->dynamics_inputs, sets.dynamics_inputs);
  EXPECT_EQ(unicycle->policy_inputs, sets.policy_inputs);
  EXPECT_EQ(unicycle->learner_state_dim(), static_cast<int>(sets.predicted.size()));
  for (size_t k = 0; k < sets.predicted.size(); ++k)
    EXPECT_EQ(unicycle->learner_state_names[k], sets.names[sets.predicted[k]]);
  EXPECT_EQ(unicycle->random_episodes, 10);
  EXPECT_EQ(unicycle->random_control_fraction, 0.2);
  // Its scene takes only its own cost, and studies refuse it.
  SceneOptions options;
  options.scene = "unicycle";
  const absl::StatusOr<Scene> angle = MakeScene(options);
  EXPECT_EQ(angle.status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_NE(angle.status().message().find("unknown cost 'angle' for scene 'unicycle'"),
            std::string::npos) << angle.status();
  const absl::StatusOr<const SceneDefinition*> study = RunnableScene("unicycle", "studies");
  EXPECT_NE(study.status().message().find("'unicycle' has no studies yet"), std::string::npos)
      << study.status();
  EXPECT_TRUE(RunnableScene("unicycle", "trials").ok());
  // Every scene builds with its default cost.
  for (const SceneDefinition& s : SceneCatalog()) {
    options.scene = s.name;
    options.cost = s.default_cost;
    EXPECT_TRUE(MakeScene(options).ok()) << s.name;
  }
}

// The unicycle's real episodes: the plant integrates 12, the learner sees
// UnicycleGpState of them (true and observed), the cost is loss_unicycle of
// the true post-step GP state, and the episode ends when it falls.
TEST(SceneCatalogTest, UnicycleEpisodesShowTheLearnerItsGpState) {
  SceneOptions options;
  options.scene = "unicycle";
  options.cost = "unicycle";
  options.horizon = 67;
  absl::StatusOr<Scene> scene = MakeScene(options);
  ASSERT_TRUE(scene.ok()) << scene.status();
  EXPECT_EQ(scene->state_dim(), 10);
  EXPECT_EQ(scene->plant->state_dim(), 12);
  EXPECT_EQ(scene->plant_mu0.size(), 12);
  // A constant wheel torque tips it over well within 10 s.
  const MultiController push = [](const Vector& o) {
    EXPECT_EQ(o.size(), 10);
    return (Vector(2) << 0.0, 20.0).finished();
  };
  Rng start_rng(7, Stream::kInitialState), noise_rng(7, Stream::kObservationNoise);
  Episode episode;
  ASSERT_TRUE(RunEpisode(*scene, push, &start_rng, &noise_rng, &episode).ok());
  ASSERT_TRUE(episode.ended);
  ASSERT_LT(episode.steps, 67);
  EXPECT_EQ(episode.states.rows(), episode.steps + 1);
  EXPECT_EQ(episode.states.cols(), 10);
  EXPECT_EQ(episode.forces.size(), 2 * episode.steps);
  // Replay the plant with the same draws: states, observations and costs
  // are the map of the plant's.
  Rng start_again(7, Stream::kInitialState), noise_again(7, Stream::kObservationNoise);
  Vector x(12);
  for (int m = 0; m < 12; ++m) x(m) = scene->plant_mu0(m) + scene->plant_initial_std(m) * start_again.Normal();
  const double rw = scene->definition->unicycle.wheel_radius;
  for (int t = 0; t <= episode.steps; ++t) {
    Vector o(12);
    for (int m = 0; m < 12; ++m) o(m) = x(m) + scene->observation_noise_std(m) * noise_again.Normal();
    EXPECT_EQ(Vector(episode.states.row(t).transpose()), UnicycleGpState(x, rw)) << t;
    EXPECT_EQ(Vector(episode.observations.row(t).transpose()), UnicycleGpState(o, rw)) << t;
    if (t == episode.steps) break;
    Vector next;
    ASSERT_TRUE(scene->plant->Step(x, episode.forces.segment(2 * t, 2), &next).ok());
    x = next;
    EXPECT_EQ(episode.costs(t), UnicycleCostValue(scene->definition->unicycle_cost, UnicycleGpState(x, rw)));
  }
  // The step after the last kept one falls; it and the rest cost 1 each.
  Vector fallen;
  ASSERT_TRUE(scene->plant->Step(x, (Vector(2) << 0.0, 20.0).finished(), &fallen).ok());
  EXPECT_TRUE(scene->EpisodeEnds(fallen));
  for (int t = episode.steps; t < 67; ++t) EXPECT_EQ(episode.costs(t), 1.0);
  EXPECT_DOUBLE_EQ(episode.total_cost, episode.costs.sum());
}

// PILCO's settings as the notes give them (a few of each scene's numbers).
TEST(SceneCatalogTest, PilcoSettings) {
  const SceneDefinition& pendulum = *FindSceneDefinition("pendulum");
  EXPECT_EQ(pendulum.horizon, 40);
  EXPECT_EQ(pendulum.max_control(0), 2.5);
  EXPECT_EQ(pendulum.dynamics_inputs, (std::vector<int>{0, 2, 3}));
  const SceneDefinition& cdp = *FindSceneDefinition("cart-double-pendulum");
  EXPECT_EQ(cdp.horizon, 100);
  EXPECT_EQ(cdp.dt, 0.05);
  EXPECT_EQ(cdp.inducing_inputs, 400);
  EXPECT_EQ(cdp.dynamics_inputs, (std::vector<int>{0, 1, 2, 3, 6, 7, 8, 9}));
  const SceneDefinition& dp = *FindSceneDefinition("double-pendulum");
  EXPECT_EQ(dp.control_dim(), 2);
  EXPECT_EQ(dp.dynamics_inputs, (std::vector<int>{0, 1, 4, 5, 6, 7}));
  const SceneDefinition& pendubot = *FindSceneDefinition("pendubot");
  EXPECT_EQ(pendubot.control_dim(), 1);
  EXPECT_EQ(pendubot.saturating_cost.widths, std::vector<double>{0.25});
  EXPECT_EQ(pendubot.evaluations_per_line_search, 20);
}

// The cart-pole's saturating cost is the tip cost: C z - C z_t is the tip's
// offset from the upright tip.
TEST(SceneCatalogTest, CartPoleSaturatingCostIsTheTipDistance) {
  const SceneDefinition& s = *FindSceneDefinition("cartpole-swingup");
  Vector x(4);
  x << 0.3, 2.0, 1.0, -1.0;
  const Vector dz = AugmentState(x, s.angle_indices) - AugmentState(s.target, s.angle_indices);
  const double d2 = std::pow(0.3 + 0.5 * std::sin(2.0), 2) + std::pow(0.5 * std::cos(2.0) + 0.5, 2);
  EXPECT_NEAR(dz.dot(s.saturating_cost.q * dz), d2, 1e-14);
}

TEST(SceneCatalogTest, AugmentStateAppendsSinAndCosInAngleOrder) {
  Vector x(4);
  x << 1.0, 2.0, 0.5, -0.25;
  const Vector z = AugmentState(x, {2, 3});
  ASSERT_EQ(z.size(), 8);
  EXPECT_EQ(z.head(4), x);
  EXPECT_EQ(z(4), std::sin(0.5));
  EXPECT_EQ(z(5), std::cos(0.5));
  EXPECT_EQ(z(6), std::sin(-0.25));
  EXPECT_EQ(z(7), std::cos(-0.25));
}

}  // namespace scene_catalog_test
}  // namespace totalgrad::tasks
