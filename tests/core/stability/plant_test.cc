// Stability suite, stiff plants (docs/stability.md): the real cart-pole's
// adaptive Dormand-Prince integrator either meets its tolerance, and then
// agrees with a much finer fixed-step reference, or reports that it cannot
// with a status naming the cause and leaves the caller's state untouched.
//
// The reference is classical RK4 with n and 2n substeps; the two must agree
// to 1e-11 (so the reference is converged) before the adaptive result is
// compared with it.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <string>

#include "core/ode/integrator.h"
#include "core/tasks/cartpole.h"
#include "core/tasks/scene.h"
#include "tests/testutil/testutil.h"

namespace totalgrad::tasks {
namespace plant_test {

State MakeState(double s, double beta, double s_dot, double beta_dot) {
  State x;
  x << s, beta, s_dot, beta_dot;
  return x;
}

// RK4 over one control period with `substeps` equal steps.
State Rk4Reference(const CartPole& plant, const State& x, double force, int substeps) {
  const ode::Rhs rhs = [&](const Vector& z, Vector* dzdt) {
    *dzdt = plant.Derivative(State(z), force);
  };
  Vector z = x;
  ode::IntegrateRk4(rhs, plant.params().dt, substeps, &z);
  return State(z);
}

// Steps `plant` once and checks the result against a converged RK4 reference.
// Returns the report through *report.
void ExpectStepMatchesReference(const CartPole& plant, const State& x, double force,
                                int substeps, double tolerance, ode::IntegrationReport* report) {
  State next;
  const absl::Status st = plant.Step(x, force, &next, report);
  TG_ASSERT_OK(st);
  ASSERT_TRUE(next.allFinite());
  const State fine = Rk4Reference(plant, x, force, substeps);
  const State finer = Rk4Reference(plant, x, force, 2 * substeps);
  const double scale = 1.0 + finer.lpNorm<Eigen::Infinity>();
  ASSERT_LT((fine - finer).lpNorm<Eigen::Infinity>(), 1e-11 * scale)
      << "the reference itself is not converged";
  const double diff = (next - finer).lpNorm<Eigen::Infinity>();
  EXPECT_LT(diff, tolerance * scale) << "adaptive " << next.transpose() << " reference "
                                     << finer.transpose();
  std::printf("  %d accepted, %d rejected steps, smallest %.3g s; |adaptive - rk4| = %.3g\n",
              report->accepted_steps, report->rejected_steps, report->smallest_step, diff);
}

// Friction 1e4 N/(m/s): the cart velocity decays with rate ~4b/(4(M+m) -
// 3m cos^2) ~ 1.6e4 1/s, so the explicit method is limited by stability, not
// accuracy, to steps of ~2e-4 s. It must still get there and be right.
TEST(StiffPlant, Friction1e4MeetsToleranceAndMatchesFineReference) {
  CartPoleParams params;
  params.friction = 1e4;
  const CartPole plant(params);
  ode::IntegrationReport report;
  ExpectStepMatchesReference(plant, MakeState(0.2, 1.0, 2.0, -3.0), 10.0, 200000, 1e-8, &report);
  EXPECT_GT(report.accepted_steps, 100);  // stability-limited, many steps
  EXPECT_LT(report.smallest_step, 1e-3);
}

// Friction 1e4 with 0.1 g masses: rate ~8e7 1/s, i.e. ~2.5e6 stable steps per
// 0.1 s, beyond the 200000-step budget. The step must fail with
// ResourceExhausted naming the budget, and leave *next untouched.
TEST(StiffPlant, Friction1e4WithTinyMassesReportsTheStepBudget) {
  CartPoleParams params;
  params.friction = 1e4;
  params.cart_mass = 1e-4;
  params.pole_mass = 1e-4;
  const CartPole plant(params);
  const State sentinel = MakeState(7, 7, 7, 7);
  State next = sentinel;
  ode::IntegrationReport report;
  const absl::Status st = plant.Step(MakeState(0.2, 1.0, 2.0, -3.0), 10.0, &next, &report);
  EXPECT_EQ(st.code(), absl::StatusCode::kResourceExhausted) << st;
  EXPECT_NE(st.message().find("cart-pole step"), std::string::npos) << st;
  EXPECT_NE(st.message().find("step budget"), std::string::npos) << st;
  EXPECT_EQ(next, sentinel);
  EXPECT_EQ(report.accepted_steps + report.rejected_steps, params.integrator.max_steps);
}

// A 1 mm pole oscillates at ~150 rad/s (oscillatory, not dissipative,
// stiffness): accuracy-limited steps, still within tolerance.
TEST(StiffPlant, PoleLength1em3MeetsToleranceAndMatchesFineReference) {
  CartPoleParams params;
  params.pole_length = 1e-3;
  const CartPole plant(params);
  ode::IntegrationReport report;
  ExpectStepMatchesReference(plant, MakeState(0.0, 0.5, 0.3, 2.0), -4.0, 20000, 1e-8, &report);
  EXPECT_GT(report.accepted_steps, 10);
}

TEST(StiffPlant, PoleMass1em4MatchesFineReference) {
  CartPoleParams params;
  params.pole_mass = 1e-4;
  const CartPole plant(params);
  ode::IntegrationReport report;
  ExpectStepMatchesReference(plant, MakeState(0.1, 2.5, -1.0, 6.0), 7.0, 4000, 1e-9, &report);
}

// A 0.1 g cart under a 0.5 kg pole: the denominator 4(M+m) - 3m cos^2 drops to
// ~0.5, fast but benign.
TEST(StiffPlant, CartMass1em4MatchesFineReference) {
  CartPoleParams params;
  params.cart_mass = 1e-4;
  const CartPole plant(params);
  ode::IntegrationReport report;
  ExpectStepMatchesReference(plant, MakeState(0.1, 2.5, -1.0, 6.0), 7.0, 4000, 1e-9, &report);
}

// dt = 0.5 s: one control period is longer than a classical RK4 step can be
// (omega dt ~ 3.4 > 2.8), but the adaptive integrator subdivides it.
TEST(StiffPlant, Dt0p5MeetsToleranceAndMatchesFineReference) {
  CartPoleParams params;
  params.dt = 0.5;
  const CartPole plant(params);
  ode::IntegrationReport report;
  ExpectStepMatchesReference(plant, MakeState(0.0, 3.0, 0.0, 0.0), 10.0, 20000, 1e-8, &report);
  EXPECT_GT(report.accepted_steps, 1);
}

// Whole episodes on the stiff-but-feasible plants: finite states and costs in
// [0, 1] under a saturated bang-bang controller (the trial's scene path).
TEST(StiffPlant, EpisodesOnStiffPlantsStayFinite) {
  struct Case {
    const char* name;
    CartPoleParams plant;
  };
  Case cases[4];
  cases[0].name = "friction 1e4";
  cases[0].plant.friction = 1e4;
  cases[1].name = "pole length 1e-3";
  cases[1].plant.pole_length = 1e-3;
  cases[2].name = "pole mass 1e-4";
  cases[2].plant.pole_mass = 1e-4;
  cases[3].name = "dt 0.5";
  cases[3].plant.dt = 0.5;
  for (const Case& c : cases) {
    SceneOptions options;
    options.cost = "tip";  // measures this plant's pole
    options.horizon = 8;
    options.plant = c.plant;
    absl::StatusOr<Scene> scene = MakeScene(options);
    TG_ASSERT_OK(scene.status());
    Rng start(3, Stream::kInitialState), noise(3, Stream::kObservationNoise);
    const Controller bang = [](const State& o) { return o(2) > 0 ? -10.0 : 10.0; };
    Episode episode;
    const absl::Status st = RunEpisode(*scene, bang, &start, &noise, &episode);
    ASSERT_TRUE(st.ok()) << c.name << ": " << st;
    EXPECT_TRUE(episode.states.allFinite()) << c.name;
    EXPECT_TRUE((episode.costs.array() >= 0).all() && (episode.costs.array() <= 1).all())
        << c.name;
  }
}

// The infeasible plant inside an episode: the failure names the step, never
// a NaN state.
TEST(StiffPlant, EpisodeOnInfeasiblePlantNamesTheStepAndTheBudget) {
  SceneOptions options;
  options.horizon = 3;
  options.plant.friction = 1e4;
  options.plant.cart_mass = 1e-4;
  options.plant.pole_mass = 1e-4;
  options.plant.integrator.max_steps = 20000;  // keep the test fast
  absl::StatusOr<Scene> scene = MakeScene(options);
  TG_ASSERT_OK(scene.status());
  Rng start(3, Stream::kInitialState), noise(3, Stream::kObservationNoise);
  Episode episode;
  const absl::Status st = RunEpisode(
      *scene, [](const State&) { return 1.0; }, &start, &noise, &episode);
  EXPECT_FALSE(st.ok());
  EXPECT_NE(st.message().find("step budget"), std::string::npos) << st;
  EXPECT_NE(st.message().find("step 0"), std::string::npos) << st;
}

}  // namespace plant_test
}  // namespace totalgrad::tasks
