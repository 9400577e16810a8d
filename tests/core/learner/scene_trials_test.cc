// Every method runs a short trial on every scene of the catalog that the
// learners support (every method on every scene: several angles and the
// double pendulum's two torques included) with finite numbers and no
// non-finite gradient, deterministically.
#include <gtest/gtest.h>

#include <cmath>
#include <string>
#include <vector>

#include "core/diff/gradient_checker.h"
#include "core/estimators/rp.h"
#include "core/gp/training.h"
#include "core/learner/evaluation.h"
#include "core/learner/problem_builder.h"
#include "core/learner/trial.h"
#include "core/tasks/scene_catalog.h"
#include "tests/testutil/test_base.h"

namespace totalgrad::learner {
namespace scene_trials_test {

// As a user's options: the scene's defaults (its cost and policy class:
// the unicycle's loss_unicycle and linear policy) under the pairs.
TrialOptions Short(const std::string& scene, const std::string& method) {
  absl::StatusOr<TrialOptions> o = TrialOptionsFromPairs({
      {"scene", scene}, {"method", method}, {"episodes", "1"}, {"policy_steps", "3"},
      {"particles", "8"}, {"eval_rollouts", "2"}, {"horizon", "8"}, {"basis_functions", "6"},
      {"gp_iterations", "10"}, {"predicted_cost_particles", "10"}, {"seed", "3"}});
  EXPECT_TRUE(o.ok()) << o.status();
  return o.ok() ? *o : TrialOptions{};
}

// Runs `o` twice: two episodes (the random one and one learned), finite
// numbers, no non-finite gradient, the same bits both times. Returns the
// learned episode's result.
EpisodeResult RunTwiceFiniteAndSame(const TrialOptions& o) {
  EXPECT_TRUE(o.Validate().ok()) << o.Validate();
  absl::StatusOr<TrialSummary> a = RunTrial(o, nullptr);
  absl::StatusOr<TrialSummary> b = RunTrial(o, nullptr);
  EXPECT_TRUE(a.ok()) << a.status();
  EXPECT_TRUE(b.ok()) << b.status();
  if (!a.ok() || !b.ok() || a->episodes.size() != 2u || b->episodes.size() != 2u) {
    ADD_FAILURE() << "expected two episodes";
    return {};
  }
  const EpisodeResult& r = a->episodes[1];
  EXPECT_TRUE(std::isfinite(r.real_cost));
  EXPECT_TRUE(std::isfinite(r.eval_cost_mean));
  EXPECT_TRUE(std::isfinite(r.predicted_cost));
  EXPECT_TRUE(r.policy_parameters.allFinite());
  EXPECT_EQ(r.flags.non_finite_gradients, 0);
  EXPECT_EQ(r.eval_cost_mean, b->episodes[1].eval_cost_mean);
  EXPECT_EQ(r.policy_parameters, b->episodes[1].policy_parameters);
  return r;
}

bool Supported(const tasks::SceneDefinition& scene, estimators::Method) {
  // Every method on every scene of the catalog that has trials (all of
  // them since the unicycle's).
  return scene.trials_unavailable.empty();
}

TEST(SceneTrials, EveryMethodOnEverySupportedSceneIsFiniteAndDeterministic) {
  int ran = 0, multi_control = 0, unicycle = 0;
  for (const tasks::SceneDefinition& scene : tasks::SceneCatalog()) {
    for (const auto& [method, name] : estimators::MethodNames()) {
      if (!Supported(scene, method)) continue;
      SCOPED_TRACE(scene.name + " " + name);
      const EpisodeResult r = RunTwiceFiniteAndSame(Short(scene.name, name));
      // On the new scenes every method sees the scene's index sets by
      // default: GP inputs z(dynamics_inputs) and u.
      if (scene.plant != tasks::PlantKind::kCartPole) {
        EXPECT_EQ(r.hyperparameters.num_inputs(),
                  static_cast<int>(scene.dynamics_inputs.size()) + scene.control_dim());
      }
      // The policy has one weight column per control: C x |policy inputs|
      // centres, the length-scales, C x F weights (C = 6 here); the
      // unicycle's linear policy F x |policy inputs| weights and F offsets.
      const int inputs = static_cast<int>(scene.policy_inputs.size());
      if (scene.policy_class == "linear") {
        EXPECT_EQ(r.policy_parameters.size(), scene.control_dim() * (inputs + 1));
      } else if (method != estimators::Method::kPilco &&
                 scene.plant != tasks::PlantKind::kCartPole) {
        EXPECT_EQ(r.policy_parameters.size(), 6 * inputs + inputs + 6 * scene.control_dim());
      }
      if (scene.control_dim() > 1) ++multi_control;
      if (scene.plant == tasks::PlantKind::kUnicycle) ++unicycle;
      ++ran;
    }
  }
  // Six scenes (the double pendulum's and the unicycle's two torques
  // included) x 9 methods.
  EXPECT_GE(ran, 6 * 9);
  EXPECT_EQ(multi_control, 18);
  EXPECT_EQ(unicycle, 9);
}

// The unicycle's episode 0 is PILCO's ten random rollouts at a fifth of the
// torque bounds: 10 x 8 transitions, fewer where one fell; its real cost is
// their mean, at most H = 8. A rollout that fell is never held.
TEST(SceneTrials, UnicycleRandomRolloutsAndFallsAreNotHeld) {
  TrialOptions o = Short("unicycle", "PILCO");
  TG_ASSERT_OK(o.Validate());
  absl::StatusOr<tasks::Scene> scene = tasks::MakeScene(o.scene);
  TG_ASSERT_OK(scene.status());
  EXPECT_EQ(scene->random_episodes, 10);
  EXPECT_EQ(scene->random_control_fraction, 0.2);
  struct Counter : TrialObserver {
    void OnEpisode(const EpisodeResult&) override {}
    void OnCheckpoint(const TrialCheckpoint& c) override {
      if (c.episode == 0) transitions = static_cast<int>(c.states.rows());
    }
    bool WantsCheckpoints() override { return true; }
    int transitions = -1;
  } counter;
  absl::StatusOr<TrialSummary> a = RunTrial(o, &counter);
  TG_ASSERT_OK(a.status());
  EXPECT_GT(counter.transitions, 8);  // more than one rollout's
  EXPECT_LE(counter.transitions, 80);
  EXPECT_LE(a->episodes[0].real_cost, 8.0);
  EXPECT_EQ(a->episodes[0].trajectories.real.states.cols(), 10);
  // At the goal throughout: held, unless the episode ended.
  tasks::Episode still;
  still.steps = 8;
  still.states = RowMatrix::Zero(9, 10);
  EXPECT_TRUE(RolloutHeld(*scene, still, 0.4, 3));
  still.ended = true;
  EXPECT_FALSE(RolloutHeld(*scene, still, 0.4, 3));
}

// PILCO's linear policy (policy = linear) for every method, on the
// cart-pole balance (one force) and the double pendulum (two torques):
// finite and deterministic, with F (Ep + 1) parameters.
TEST(SceneTrials, EveryMethodWithTheLinearPolicyIsFiniteAndDeterministic) {
  int ran = 0;
  for (const std::string scene_name : {"cartpole-balance", "double-pendulum"}) {
    for (const auto& [method, name] : estimators::MethodNames()) {
      SCOPED_TRACE(scene_name + " " + name);
      TrialOptions o = Short(scene_name, name);
      TG_ASSERT_OK(SetTrialOption("policy", "linear", &o));
      const EpisodeResult r = RunTwiceFiniteAndSame(o);
      absl::StatusOr<tasks::Scene> scene = tasks::MakeScene(o.scene);
      TG_ASSERT_OK(scene.status());
      const std::vector<int> angles = FeatureAngles(o, *scene);
      const int ep = scene->state_dim() + static_cast<int>(angles.size());
      EXPECT_EQ(r.policy_parameters.size(), scene->control_dim() * (ep + 1));
      ++ran;
    }
  }
  EXPECT_EQ(ran, 2 * 9);
}

// The two-control scene on the other model and feature paths: FITC once the
// data exceed M (here M = 10 < 16 transitions after episode 1) and the raw
// state (no angle adapters), for a pathwise, a jump and a combined method.
TEST(SceneTrials, DoublePendulumOnFitcAndRawFeatures) {
  for (const std::string method : {"RP", "LR", "TP"}) {
    for (const auto& [key, value] : std::vector<std::pair<std::string, std::string>>{
             {"gp_inducing", "10"}, {"angle_features", "raw"}}) {
      SCOPED_TRACE(method + " " + key + "=" + value);
      TrialOptions o = Short("double-pendulum", method);
      TG_ASSERT_OK(SetTrialOption("episodes", "2", &o));
      TG_ASSERT_OK(SetTrialOption(key, value, &o));
      absl::StatusOr<TrialSummary> a = RunTrial(o, nullptr);
      TG_ASSERT_OK(a.status());
      ASSERT_EQ(a->episodes.size(), 3u);
      for (size_t e = 1; e < a->episodes.size(); ++e) {
        const EpisodeResult& r = a->episodes[e];
        EXPECT_TRUE(std::isfinite(r.eval_cost_mean));
        EXPECT_TRUE(std::isfinite(r.predicted_cost));
        EXPECT_TRUE(r.policy_parameters.allFinite());
        EXPECT_EQ(r.flags.non_finite_gradients, 0);
      }
      if (key == "angle_features") {
        // Raw: the GP sees the 4 states and the 2 torques, the policy the 4 states.
        EXPECT_EQ(a->episodes[2].hyperparameters.num_inputs(), 6);
        EXPECT_EQ(a->episodes[2].policy_parameters.size(), 6 * 4 + 4 + 6 * 2);
      }
    }
  }
}

// PILCO on the two-angle scenes with PILCO's own loss (lossSat on z with
// the scene's Q and widths, the closed form through the joint trig block):
// the double pendulum (two torques) and the pendubot (one) run a learned
// episode with finite numbers, deterministically; the predicted cost is a sum
// of H per-step costs in [0, 1]. Tiny budgets: this only shows the path runs.
TEST(SceneTrials, PilcoWithTheSaturatingCostOnTwoAngleScenes) {
  for (const std::string scene : {"double-pendulum", "pendubot"}) {
    SCOPED_TRACE(scene);
    TrialOptions o = Short(scene, "PILCO");
    TG_ASSERT_OK(SetTrialOption("cost", "saturating", &o));
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
    EXPECT_GE(r.predicted_cost, 0.0);
    EXPECT_LE(r.predicted_cost, 8.0);  // horizon 8, each step's cost <= 1
    EXPECT_TRUE(r.policy_parameters.allFinite());
    EXPECT_EQ(r.eval_cost_mean, b->episodes[1].eval_cost_mean);
    EXPECT_EQ(r.policy_parameters, b->episodes[1].policy_parameters);
  }
}

// The unicycle's particle problem as a trial builds it (its GP on 9 of the
// 10 learner-state entries through InputSubsetDynamics, loss_unicycle's
// gradient, the linear policy, no angle features): RP's gradient against
// central differences of the fixed-noise objective, on a GP of real
// unicycle transitions. A wrong Jacobian in any of the three fails it.
TEST(SceneTrials, UnicycleModelProblemRpGradientMatchesFiniteDifferences) {
  tasks::SceneOptions scene_options;
  scene_options.scene = "unicycle";
  scene_options.cost = "unicycle";
  scene_options.horizon = 6;
  absl::StatusOr<tasks::Scene> scene = tasks::MakeScene(scene_options);
  TG_ASSERT_OK(scene.status());
  Transitions data;
  Rng action(4, Stream::kExplorationAction);
  for (int r = 0; r < 4; ++r) {
    const tasks::MultiController random = [&](const Vector&) {
      return Vector((Vector(2) << action.Uniform(-2, 2), action.Uniform(-10, 10)).finished());
    };
    Rng start(4, Stream::kInitialState, r), noise(4, Stream::kObservationNoise, r);
    tasks::Episode episode;
    TG_ASSERT_OK(tasks::RunEpisode(*scene, random, &start, &noise, &episode));
    data.Append(episode);
  }
  ASSERT_GE(data.size(), 8);
  const GpTrainingSet set = MakeGpTrainingSet(data, {}, scene->dynamics_inputs);
  ASSERT_EQ(set.inputs.cols(), 9 + 2);  // dyni and the torques
  ASSERT_EQ(set.targets.cols(), 10);
  const gp::GpHyperparameters hyperparameters = gp::InitialHyperparameters(set.inputs, set.targets);
  TrialPolicy policy(policy::PolicyClass::kLinear, 0, 10, scene->max_control);
  Rng init(6, Stream::kPolicyInit);
  policy.linear().Initialize(0.5, &init);
  absl::StatusOr<ModelProblem> model = ModelProblem::Build(
      set, hyperparameters, SparseModelFit{}, {}, &policy, *scene, 1.0, nullptr);
  TG_ASSERT_OK(model.status());
  const int particles = 4;
  const Vector theta0 = policy.parameters();
  const auto objective = [&](const Vector& theta) {
    policy.set_parameters(theta);
    Rng rng(11, Stream::kParticleNoise);
    estimators::Rollout rollout;
    EXPECT_TRUE(estimators::SimulateParticles(model->problem(), particles, {}, &rng, &rollout).ok());
    policy.set_parameters(theta0);
    return rollout.objective;
  };
  Rng rng(11, Stream::kParticleNoise);
  estimators::RpEstimator rp;
  estimators::EstimateOptions eo;
  eo.particles = particles;
  estimators::GradientEstimate estimate;
  TG_ASSERT_OK(rp.Estimate(model->problem(), eo, &rng, &estimate));
  ASSERT_EQ(estimate.gradient.size(), 2 * 11);
  EXPECT_NEAR(estimate.objective, objective(theta0), 1e-12);
  const diff::VectorFunction f = [&](const Vector& theta, Vector* out) {
    *out = Vector::Constant(1, objective(theta));
    return std::isfinite((*out)(0));
  };
  diff::CheckOptions check;
  check.relative_tolerance = 1e-5;
  check.absolute_tolerance = 1e-8;
  const diff::CheckResult r = diff::CheckJacobian(f, theta0, estimate.gradient.transpose(), check);
  EXPECT_TRUE(r.ok) << r.log;
  EXPECT_GT(estimate.gradient.norm(), 1e-6) << "a zero gradient would pass trivially";
}

TEST(SceneTrials, CartPoleOptionsAreRefusedOnOtherScenes) {
  // The cart-pole's plant options do not apply to PILCO's scenes.
  TrialOptions o = Short("pendulum", "RP");
  TG_ASSERT_OK(SetTrialOption("cart_mass", "2", &o));
  EXPECT_NE(o.Validate().message().find("cart-pole"), std::string::npos) << o.Validate();
}

}  // namespace scene_trials_test
}  // namespace totalgrad::learner
