// Every method runs a short trial on every scene of the catalog that the
// learners support (one control; PILCO's moment matching: at most one angle)
// with finite numbers and no non-finite gradient, deterministically; the
// scenes they do not support yet are refused by name before any work.
#include <gtest/gtest.h>

#include <cmath>
#include <string>
#include <vector>

#include "core/learner/trial.h"
#include "core/tasks/scene_catalog.h"
#include "tests/testutil/test_base.h"

namespace totalgrad::learner {
namespace {

TrialOptions Short(const std::string& scene, const std::string& method) {
  TrialOptions o;
  for (const auto& [k, v] : std::vector<std::pair<std::string, std::string>>{
           {"scene", scene}, {"method", method}, {"episodes", "1"}, {"policy_steps", "3"},
           {"particles", "8"}, {"eval_rollouts", "2"}, {"horizon", "8"}, {"basis_functions", "6"},
           {"gp_iterations", "10"}, {"predicted_cost_particles", "10"}, {"seed", "3"}}) {
    EXPECT_TRUE(SetTrialOption(k, v, &o).ok()) << k << "=" << v;
  }
  return o;
}

bool Supported(const tasks::SceneDefinition& scene, estimators::Method method) {
  if (scene.control_dim() != 1) return false;
  return method != estimators::Method::kPilco || scene.num_angles() <= 1;
}

TEST(SceneTrials, EveryMethodOnEverySupportedSceneIsFiniteAndDeterministic) {
  int ran = 0;
  for (const tasks::SceneDefinition& scene : tasks::SceneCatalog()) {
    for (const auto& [method, name] : estimators::MethodNames()) {
      if (!Supported(scene, method)) continue;
      SCOPED_TRACE(scene.name + " " + name);
      const TrialOptions o = Short(scene.name, name);
      TG_ASSERT_OK(o.Validate());
      absl::StatusOr<TrialSummary> a = RunTrial(o, nullptr);
      TG_ASSERT_OK(a.status());
      absl::StatusOr<TrialSummary> b = RunTrial(o, nullptr);
      TG_ASSERT_OK(b.status());
      ASSERT_EQ(a->episodes.size(), 2u);
      const EpisodeResult& r = a->episodes[1];
      EXPECT_TRUE(std::isfinite(r.real_cost));
      EXPECT_TRUE(std::isfinite(r.eval_cost_mean));
      EXPECT_TRUE(std::isfinite(r.predicted_cost));
      EXPECT_TRUE(r.policy_parameters.allFinite());
      EXPECT_EQ(r.flags.non_finite_gradients, 0);
      EXPECT_EQ(r.eval_cost_mean, b->episodes[1].eval_cost_mean);
      EXPECT_EQ(r.policy_parameters, b->episodes[1].policy_parameters);
      // On the new scenes every method sees the scene's index sets by
      // default: GP inputs z(dynamics_inputs) and u.
      if (scene.plant != tasks::PlantKind::kCartPole) {
        EXPECT_EQ(r.hyperparameters.num_inputs(),
                  static_cast<int>(scene.dynamics_inputs.size()) + scene.control_dim());
      }
      ++ran;
    }
  }
  EXPECT_GE(ran, 4 * 8 + 3);  // four one-control scenes x 8 particle methods, PILCO on three
}

TEST(SceneTrials, WhatTheLearnersDoNotSupportYetIsRefusedByName) {
  const absl::Status two_controls = Short("double-pendulum", "RP").Validate();
  EXPECT_EQ(two_controls.code(), absl::StatusCode::kInvalidArgument);
  EXPECT_NE(two_controls.message().find("2 controls"), std::string::npos) << two_controls;
  const absl::StatusOr<TrialSummary> two_angles = RunTrial(Short("pendubot", "PILCO"), nullptr);
  EXPECT_EQ(two_angles.status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_NE(two_angles.status().message().find("2 angles"), std::string::npos) << two_angles.status();
  // The cart-pole's plant options do not apply to PILCO's scenes.
  TrialOptions o = Short("pendulum", "RP");
  TG_ASSERT_OK(SetTrialOption("cart_mass", "2", &o));
  EXPECT_NE(o.Validate().message().find("cart-pole"), std::string::npos) << o.Validate();
}

}  // namespace
}  // namespace totalgrad::learner
