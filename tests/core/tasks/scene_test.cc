#include "core/tasks/scene.h"

#include <gtest/gtest.h>

#include <cmath>
#include <functional>
#include <limits>
#include <numbers>
#include <string>
#include <vector>

#include "tests/testutil/testutil.h"

namespace totalgrad::tasks {
namespace scene_test {

constexpr double kPi = std::numbers::pi;
constexpr double kNan = std::numeric_limits<double>::quiet_NaN();

State MakeState(double s, double beta, double s_dot, double beta_dot) {
  State x;
  x << s, beta, s_dot, beta_dot;
  return x;
}

const State kBaseNoiseStd = MakeState(0.01, kPi / 180.0, 0.1, 10.0 * kPi / 180.0);

Scene MustMakeScene(const SceneOptions& options) {
  absl::StatusOr<Scene> scene = MakeScene(options);
  EXPECT_TRUE(scene.ok()) << scene.status();
  if (scene.ok()) return *std::move(scene);
  return Scene();
}

// A bounded feedback law on the observation, so that observation noise
// changes the trajectory.
double Feedback(const State& o) { return 10.0 * std::tanh(o(0) + 0.5 * o(2) - 0.3 * o(3)); }

// The cart-pole scenes' plant is the cart-pole (the scene holds it as a Plant).
const CartPole& CartPoleOf(const Scene& scene) { return dynamic_cast<const CartPole&>(*scene.plant); }

TEST(MakeSceneTest, SwingUpDefaults) {
  const Scene scene = MustMakeScene({});
  EXPECT_EQ(scene.name, "cartpole-swingup");
  EXPECT_EQ(scene.mu0, State::Zero());
  EXPECT_EQ(scene.target, MakeState(0, kPi, 0, 0));
  EXPECT_EQ(scene.initial_std, State::Constant(0.1));
  EXPECT_TRUE(testing::MatricesNear(scene.observation_noise_std, kBaseNoiseStd, 0, 1e-15));
  EXPECT_EQ(scene.horizon, 30);
  ASSERT_NE(scene.cost, nullptr);
  EXPECT_EQ(scene.cost->Name(), "angle");
  EXPECT_EQ(scene.cost->Value(scene.target), 0.0);
  EXPECT_EQ(CartPoleOf(scene).params().dt, 0.1);
}

TEST(MakeSceneTest, BalanceTipAndNoiseScaling) {
  SceneOptions options;
  options.scene = "cartpole-balance";
  options.cost = "tip";
  options.noise_k = 4.0;
  options.horizon = 12;
  options.initial_std = 0.02;
  options.plant.pole_length = 0.6;
  const Scene scene = MustMakeScene(options);
  EXPECT_EQ(scene.mu0, MakeState(0, kPi, 0, 0));
  EXPECT_EQ(scene.target, scene.mu0);
  EXPECT_EQ(scene.horizon, 12);
  EXPECT_EQ(scene.initial_std, State::Constant(0.02));
  // Variance multiplier k = 4: standard deviations double.
  EXPECT_TRUE(
      testing::MatricesNear(scene.observation_noise_std, 2.0 * kBaseNoiseStd, 0, 1e-15));
  ASSERT_NE(scene.cost, nullptr);
  const auto* tip = dynamic_cast<const TipCost*>(scene.cost.get());
  ASSERT_NE(tip, nullptr);
  EXPECT_EQ(tip->pendulum_length(), 0.6);  // the plant's pole
  EXPECT_EQ(tip->width(), 0.25);
  EXPECT_EQ(CartPoleOf(scene).params().pole_length, 0.6);
}

TEST(MakeSceneTest, ErrorsNameTheBadField) {
  struct Case {
    std::function<void(SceneOptions*)> mutate;
    std::string field;
  };
  const std::vector<Case> cases = {
      {[](SceneOptions* o) { o->scene = "acrobot"; }, "acrobot"},
      {[](SceneOptions* o) { o->scene = "acrobot"; }, "scene"},
      {[](SceneOptions* o) { o->cost = "quadratic"; }, "quadratic"},
      {[](SceneOptions* o) { o->noise_k = -1.0; }, "noise_k"},
      {[](SceneOptions* o) { o->noise_k = kNan; }, "noise_k"},
      {[](SceneOptions* o) { o->horizon = 0; }, "horizon"},
      {[](SceneOptions* o) { o->initial_std = -0.1; }, "initial_std"},
      {[](SceneOptions* o) { o->initial_std = kNan; }, "initial_std"},
      {[](SceneOptions* o) { o->plant.dt = 0.0; }, "plant.dt"},
      {[](SceneOptions* o) { o->plant.pole_length = kNan; }, "plant.pole_length"},
      {[](SceneOptions* o) { o->plant.cart_mass = -0.5; }, "plant.cart_mass"},
      {[](SceneOptions* o) { o->plant.friction = -0.1; }, "plant.friction"},
      {[](SceneOptions* o) { o->plant.max_force = 0.0; }, "plant.max_force"},
  };
  for (const Case& c : cases) {
    SceneOptions options;
    c.mutate(&options);
    const absl::StatusOr<Scene> scene = MakeScene(options);
    EXPECT_EQ(scene.status().code(), absl::StatusCode::kInvalidArgument) << c.field;
    EXPECT_NE(scene.status().message().find(c.field), std::string::npos)
        << "want '" << c.field << "' in: " << scene.status();
  }
  SceneOptions zero_noise;
  zero_noise.noise_k = 0.0;  // noise-free observations are allowed
  TG_EXPECT_OK(MakeScene(zero_noise).status());
}

absl::Status RunSeeded(const Scene& scene, uint64_t start_seed, uint64_t noise_seed,
                       Episode* episode, const Controller& controller = Feedback) {
  Rng start(start_seed, Stream::kInitialState);
  Rng noise(noise_seed, Stream::kObservationNoise);
  return RunEpisode(scene, controller, &start, &noise, episode);
}

// Issue 29: an unknown scene is named with the catalog names it begins, or
// the closest one, so "cartpole" (which `simulate` once took) points at the
// two cart-pole scenes.
TEST(MakeSceneTest, AnUnknownSceneSaysWhichWasMeant) {
  SceneOptions options;
  options.scene = "cartpole";
  absl::StatusOr<Scene> scene = MakeScene(options);
  ASSERT_FALSE(scene.ok());
  EXPECT_EQ(scene.status().message(),
            "scene: unknown scene 'cartpole' (did you mean cartpole-swingup or cartpole-balance?; "
            "known: pendulum, cartpole-swingup, cartpole-balance, cart-double-pendulum, "
            "double-pendulum, pendubot, unicycle)");
  options.scene = "pendulm";
  scene = MakeScene(options);
  ASSERT_FALSE(scene.ok());
  EXPECT_NE(scene.status().message().find("(did you mean pendulum?; known:"), std::string::npos)
      << scene.status();
  options.scene = "acrobot";
  scene = MakeScene(options);
  ASSERT_FALSE(scene.ok());
  EXPECT_NE(scene.status().message().find("unknown scene 'acrobot' ("), std::string::npos)
      << scene.status();
}

TEST(RunEpisodeTest, DeterministicForEqualSeedsDifferentOtherwise) {
  const Scene scene = MustMakeScene({});
  Episode a, b, other_start, other_noise;
  TG_ASSERT_OK(RunSeeded(scene, 1, 2, &a));
  TG_ASSERT_OK(RunSeeded(scene, 1, 2, &b));
  EXPECT_EQ(a.states, b.states);
  EXPECT_EQ(a.observations, b.observations);
  EXPECT_EQ(a.forces, b.forces);
  EXPECT_EQ(a.costs, b.costs);
  EXPECT_EQ(a.total_cost, b.total_cost);

  TG_ASSERT_OK(RunSeeded(scene, 3, 2, &other_start));
  EXPECT_NE(other_start.states.row(0), a.states.row(0));

  TG_ASSERT_OK(RunSeeded(scene, 1, 4, &other_noise));
  EXPECT_EQ(other_noise.states.row(0), a.states.row(0));  // same start stream
  EXPECT_NE(other_noise.observations.row(0), a.observations.row(0));
  EXPECT_NE(other_noise.states.row(scene.horizon), a.states.row(scene.horizon));
}

TEST(RunEpisodeTest, EpisodeIsConsistent) {
  for (const std::string cost : {"angle", "tip"}) {
    SceneOptions options;
    options.cost = cost;
    const Scene scene = MustMakeScene(options);
    std::vector<State> seen;
    const Controller recording = [&](const State& o) {
      seen.push_back(o);
      return Feedback(o);
    };
    Episode ep;
    TG_ASSERT_OK(RunSeeded(scene, 11, 12, &ep, recording));
    const int h = scene.horizon;
    ASSERT_EQ(ep.states.rows(), h + 1);
    ASSERT_EQ(ep.states.cols(), 4);
    ASSERT_EQ(ep.observations.rows(), h + 1);
    ASSERT_EQ(ep.forces.size(), h);
    ASSERT_EQ(ep.costs.size(), h);
    ASSERT_EQ(static_cast<int>(seen.size()), h);

    // x0 = mu0 + initial_std * (first four normals of the start stream).
    Rng start(11, Stream::kInitialState);
    for (int m = 0; m < 4; ++m) {
      EXPECT_EQ(ep.states(0, m), scene.mu0(m) + scene.initial_std(m) * start.Normal());
    }
    double sum = 0;
    for (int t = 0; t < h; ++t) {
      // The controller acted on the recorded observation; its force was applied.
      EXPECT_EQ(seen[t], State(ep.observations.row(t).transpose())) << "step " << t;
      EXPECT_EQ(ep.forces(t), Feedback(seen[t]));
      // Costs of the true post-step state, in [0, 1].
      const State next = ep.states.row(t + 1).transpose();
      EXPECT_EQ(ep.costs(t), scene.cost->Value(next));
      EXPECT_GE(ep.costs(t), 0.0);
      EXPECT_LE(ep.costs(t), 1.0);
      // The true state follows the plant exactly.
      State stepped;
      TG_ASSERT_OK(CartPoleOf(scene).Step(ep.states.row(t).transpose(), ep.forces(t), &stepped));
      EXPECT_EQ(stepped, next) << "step " << t;
      sum += ep.costs(t);
    }
    EXPECT_NEAR(ep.total_cost, sum, 1e-12);
    EXPECT_NEAR(ep.total_cost, ep.costs.sum(), 1e-12);
    EXPECT_GT(ep.total_cost, 0.0);
  }
}

TEST(RunEpisodeTest, ObservationNoiseHasTheSceneStd) {
  SceneOptions options;
  options.horizon = 400;
  options.noise_k = 2.0;
  const Scene scene = MustMakeScene(options);
  Episode ep;
  TG_ASSERT_OK(RunSeeded(scene, 5, 6, &ep, [](const State&) { return 0.0; }));
  const RowMatrix residual = ep.observations - ep.states;
  const double n = static_cast<double>(residual.rows());
  for (int m = 0; m < 4; ++m) {
    const Vector z = residual.col(m) / scene.observation_noise_std(m);
    const double mean = z.mean();
    const double sd = std::sqrt((z.array() - mean).square().sum() / (n - 1));
    // 401 standard normals: the mean has std 0.05, the sample std about 0.035;
    // the bounds are about 4 of those.
    EXPECT_LT(std::abs(mean), 0.2) << "dim " << m;
    EXPECT_NEAR(sd, 1.0, 0.15) << "dim " << m;
  }
}

TEST(RunEpisodeTest, ZeroNoiseObservesTheTrueState) {
  SceneOptions options;
  options.noise_k = 0.0;
  options.scene = "cartpole-balance";
  const Scene scene = MustMakeScene(options);
  Episode ep;
  TG_ASSERT_OK(RunSeeded(scene, 7, 8, &ep));
  EXPECT_EQ(ep.observations, ep.states);
}

TEST(RunEpisodeTest, NonFiniteForceFailsNamingTheStep) {
  const Scene scene = MustMakeScene({});
  int calls = 0;
  const Controller bad = [&](const State&) { return calls++ == 3 ? kNan : 1.0; };
  Episode ep;
  const absl::Status st = RunSeeded(scene, 1, 2, &ep, bad);
  EXPECT_EQ(st.code(), absl::StatusCode::kInternal) << st;
  EXPECT_NE(st.message().find("step 3"), std::string::npos) << st;
}

TEST(RunEpisodeTest, PlantFailureFailsNamingTheStep) {
  SceneOptions options;
  options.plant.integrator.max_steps = 1;
  const Scene scene = MustMakeScene(options);
  Episode ep;
  const absl::Status st = RunSeeded(scene, 1, 2, &ep);
  EXPECT_EQ(st.code(), absl::StatusCode::kInternal) << st;
  EXPECT_NE(st.message().find("step 0"), std::string::npos) << st;
}

// ------------------------------------------------------ F controls
// The double pendulum's two torques: H F forces, step-major, each step's
// controls applied together; the contract's errors.

absl::Status RunMultiSeeded(const Scene& scene, uint64_t start_seed, uint64_t noise_seed,
                            Episode* episode, const MultiController& controller) {
  Rng start(start_seed, Stream::kInitialState);
  Rng noise(noise_seed, Stream::kObservationNoise);
  return RunEpisode(scene, controller, &start, &noise, episode);
}

// Two bounded torques from the observation, different from each other.
Vector TwoTorques(const Vector& o) {
  Vector u(2);
  u << 2.0 * std::tanh(o(0) - 0.5 * (o(2) - kPi)), -2.0 * std::tanh(0.3 * o(1) + (o(3) - kPi));
  return u;
}

TEST(RunEpisodeTest, TwoControlsAreAppliedStepByStep) {
  SceneOptions options;
  options.scene = "double-pendulum";
  options.horizon = 12;
  const Scene scene = MustMakeScene(options);
  ASSERT_EQ(scene.control_dim(), 2);
  std::vector<Vector> seen;
  const MultiController recording = [&](const Vector& o) {
    seen.push_back(o);
    return TwoTorques(o);
  };
  Episode ep;
  TG_ASSERT_OK(RunMultiSeeded(scene, 3, 4, &ep, recording));
  const int h = scene.horizon, d = scene.state_dim();
  ASSERT_EQ(ep.forces.size(), 2 * h);  // u_0^1, u_0^2, u_1^1, ...
  ASSERT_EQ(static_cast<int>(seen.size()), h);
  for (int t = 0; t < h; ++t) {
    EXPECT_EQ(seen[t], Vector(ep.observations.row(t).transpose())) << "step " << t;
    const Vector u = TwoTorques(seen[t]);
    EXPECT_EQ(ep.forces(2 * t), u(0)) << "step " << t;
    EXPECT_EQ(ep.forces(2 * t + 1), u(1)) << "step " << t;
    // The plant got both torques of step t at once.
    Vector next;
    TG_ASSERT_OK(scene.plant->Step(ep.states.row(t).transpose(), u, &next));
    EXPECT_EQ(next, Vector(ep.states.row(t + 1).transpose())) << "step " << t;
    EXPECT_EQ(ep.costs(t), scene.cost->Value(next));
  }
  EXPECT_EQ(ep.states.cols(), d);
  // Each torque matters: the second one zeroed changes the trajectory.
  const MultiController first_only = [](const Vector& o) {
    Vector u = TwoTorques(o);
    u(1) = 0;
    return u;
  };
  Episode other;
  TG_ASSERT_OK(RunMultiSeeded(scene, 3, 4, &other, first_only));
  EXPECT_NE(other.states.row(h), ep.states.row(h));
}

// A one-control scene through the multi-control interface is the one-control
// episode, bit for bit.
TEST(RunEpisodeTest, OneControlThroughEitherInterfaceIsTheSame) {
  const Scene scene = MustMakeScene({});
  Episode a, b;
  TG_ASSERT_OK(RunSeeded(scene, 1, 2, &a));
  TG_ASSERT_OK(RunMultiSeeded(scene, 1, 2, &b, [](const Vector& o) {
    return Vector::Constant(1, Feedback(State(o))).eval();
  }));
  EXPECT_EQ(a.states, b.states);
  EXPECT_EQ(a.forces, b.forces);
  EXPECT_EQ(a.total_cost, b.total_cost);
}

TEST(RunEpisodeTest, WrongControlsFailNamingTheStep) {
  SceneOptions options;
  options.scene = "double-pendulum";
  const Scene scene = MustMakeScene(options);
  Episode ep;
  // A one-control controller on a two-control scene: refused before any step.
  const absl::Status one = RunSeeded(scene, 1, 2, &ep, [](const State&) { return 0.0; });
  EXPECT_EQ(one.code(), absl::StatusCode::kInvalidArgument) << one;
  EXPECT_NE(one.message().find("2 controls"), std::string::npos) << one;
  // Three controls at step 0.
  const absl::Status three =
      RunMultiSeeded(scene, 1, 2, &ep, [](const Vector&) { return Vector::Zero(3).eval(); });
  EXPECT_EQ(three.code(), absl::StatusCode::kInvalidArgument) << three;
  EXPECT_NE(three.message().find("step 0: controller returned 3 controls; the scene has 2"),
            std::string::npos)
      << three;
  // The second torque non-finite at step 2: named with its control.
  int calls = 0;
  const absl::Status nan = RunMultiSeeded(scene, 1, 2, &ep, [&](const Vector&) {
    Vector u = Vector::Zero(2);
    if (calls++ == 2) u(1) = kNan;
    return u;
  });
  EXPECT_EQ(nan.code(), absl::StatusCode::kInternal) << nan;
  EXPECT_NE(nan.message().find("step 2"), std::string::npos) << nan;
  EXPECT_NE(nan.message().find("for control 1"), std::string::npos) << nan;
}

// Episodes that end (issue 30, PILCO's plant.constraint): the cart-pole
// swing-up (start spread 0.01) with an end at |s| > 0.2 m and a constant
// push. The ended
// episode is the full one's prefix, bit for bit, up to the last state within
// the bound; the step into the end is neither kept nor costed (PILCO's
// rollout), and every step from it on costs ended_step_cost (1), so the
// total is the kept costs plus (H - T).
TEST(RunEpisodeTest, AnEpisodeEndsAtTheScenesBoundAndTheRestCostsTheMaximum) {
  SceneOptions options;
  options.horizon = 30;
  options.initial_std = 0.01;
  Scene full = MustMakeScene(options);
  ASSERT_TRUE(full.episode_end_indices.empty()) << "the cart-pole's episodes never end";
  Scene ending = full;
  ending.episode_end_indices = {0};
  ending.episode_end_bound = 0.2;
  const Controller push = [](const State&) { return 5.0; };
  Episode whole, ended;
  TG_ASSERT_OK(RunSeeded(full, 4, 5, &whole, push));
  TG_ASSERT_OK(RunSeeded(ending, 4, 5, &ended, push));
  EXPECT_FALSE(whole.ended);
  EXPECT_EQ(whole.steps, 30);
  ASSERT_TRUE(ended.ended);
  const int t = ended.steps;
  ASSERT_GT(t, 0);
  ASSERT_LT(t, 30);
  EXPECT_EQ(ended.states.rows(), t + 1);
  EXPECT_EQ(ended.observations.rows(), t + 1);
  EXPECT_EQ(ended.forces.size(), t);
  ASSERT_EQ(ended.costs.size(), 30);
  EXPECT_EQ(ended.states, whole.states.topRows(t + 1));
  EXPECT_EQ(ended.observations, whole.observations.topRows(t + 1));
  EXPECT_EQ(ended.costs.head(t), whole.costs.head(t));
  // The kept states are within the bound; the next one is not.
  EXPECT_LE(whole.states.col(0).head(t + 1).cwiseAbs().maxCoeff(), 0.2);
  EXPECT_GT(std::abs(whole.states(t + 1, 0)), 0.2);
  for (int k = t; k < 30; ++k) EXPECT_EQ(ended.costs(k), 1.0) << k;
  EXPECT_NEAR(ended.total_cost, whole.costs.head(t).sum() + (30 - t), 1e-12);
  EXPECT_GT(ended.total_cost, whole.total_cost) << "an early end must not look cheap";
}

// The unicycle's end is PILCO's: |roll| or |pitch| > pi/2 in its ODE state.
TEST(RunEpisodeTest, TheUnicycleEndsWhenRollOrPitchPassesAQuarterTurn) {
  const SceneDefinition* unicycle = FindSceneDefinition("unicycle");
  ASSERT_NE(unicycle, nullptr);
  Scene scene;
  scene.episode_end_indices = unicycle->episode_end_indices;
  scene.episode_end_bound = unicycle->episode_end_bound;
  EXPECT_EQ(scene.episode_end_indices, (std::vector<int>{Unicycle::kRoll, Unicycle::kPitch}));
  Vector x = Vector::Zero(12);
  x(Unicycle::kYaw) = 3.0;  // heading and turning are free
  x(Unicycle::kYawRate) = 40.0;
  x(Unicycle::kRoll) = 1.57;
  x(Unicycle::kPitch) = -1.57;
  EXPECT_FALSE(scene.EpisodeEnds(x));
  x(Unicycle::kRoll) = 1.571;
  EXPECT_TRUE(scene.EpisodeEnds(x));
  x(Unicycle::kRoll) = 0.0;
  x(Unicycle::kPitch) = -1.571;
  EXPECT_TRUE(scene.EpisodeEnds(x));
}

}  // namespace scene_test
}  // namespace totalgrad::tasks
