#include "core/tasks/cartpole.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <limits>
#include <numbers>
#include <vector>

#include "core/diff/gradient_checker.h"
#include "tests/testutil/testutil.h"

namespace totalgrad::tasks {
namespace cartpole_test {

constexpr double kPi = std::numbers::pi;

State MakeState(double s, double beta, double s_dot, double beta_dot) {
  State x;
  x << s, beta, s_dot, beta_dot;
  return x;
}

// Hand-evaluated right-hand sides with PILCO's constants (M = m = 0.5 kg,
// l = 0.5 m, b = 0.1, g = 9.82); the denominator 4(M+m) - 3m cos^2 is 2.5 at
// beta = 0 or pi and 4 at beta = pi/2.
TEST(CartPoleTest, DerivativeAtKnownStates) {
  const CartPole plant;
  // Hanging at rest, f = 1 N: s_ddot = 4 / 2.5, beta_ddot = -6 / (0.5 * 2.5).
  EXPECT_TRUE(testing::MatricesNear(plant.Derivative(State::Zero(), 1.0),
                                    MakeState(0, 0, 1.6, -4.8), 1e-14, 0));
  // Upright at rest, f = 1 N: the pole is pushed the other way (cos = -1).
  EXPECT_TRUE(testing::MatricesNear(plant.Derivative(MakeState(0, kPi, 0, 0), 1.0),
                                    MakeState(0, 0, 1.6, 4.8), 1e-12, 0));
  // Horizontal pole at rest, no force: beta_ddot = -6 (M+m) g / (l * 4).
  EXPECT_TRUE(testing::MatricesNear(plant.Derivative(MakeState(0.3, kPi / 2, 0, 0), 0.0),
                                    MakeState(0, 0, 0, -29.46), 1e-12, 0));
  // Horizontal pole, moving: s_ddot = (2 m l w^2 - 4 b v) / 4 with v = 1,
  // w = 2; cos beta = 0 removes force and friction from beta_ddot.
  EXPECT_TRUE(testing::MatricesNear(plant.Derivative(MakeState(0, kPi / 2, 1.0, 2.0), 0.0),
                                    MakeState(1.0, 2.0, 0.4, -29.46), 1e-12, 0));
}

// pipps-spec.md 1.8 gives trajectories of the demo's explicit Euler scheme
// (10 substeps of 0.01 s, F = 10 u) in the demo's angle convention
// theta_demo = beta - pi. Reproducing them with our Derivative checks the
// equations against an independent implementation.
TEST(CartPoleTest, EulerReproducesIndependentTestVectors) {
  const CartPole plant;
  auto euler = [&](State x, double force) {
    for (int i = 0; i < 10; ++i) x += 0.01 * plant.Derivative(x, force);
    return x;
  };
  auto from_demo = [](double x, double theta, double x_dot, double theta_dot) {
    return MakeState(x, theta - kPi, x_dot, theta_dot);
  };
  {
    State x = from_demo(0, kPi, 0, 0);
    const std::vector<double> u = {0.5, 0.5, -1.0};
    const std::vector<State> expected = {
        from_demo(0.0355264688, 3.0365069796, 0.7752222475, -2.2401717015),
        from_demo(0.1421861267, 2.7491477508, 1.3734721481, -3.3345324858),
        from_demo(0.2034804673, 2.6787778309, -0.2948750229, 2.4610156313)};
    for (size_t k = 0; k < u.size(); ++k) {
      x = euler(x, 10.0 * u[k]);
      EXPECT_TRUE(testing::MatricesNear(x, expected[k], 2e-10, 0)) << "swing-up step " << k;
    }
  }
  {
    State x = from_demo(0, 0.1, 0, 0);
    const std::vector<State> expected = {
        from_demo(0.0026601593, 0.1214625996, 0.0608091383, 0.4920948730),
        from_demo(0.0121798781, 0.1990359224, 0.1435203081, 1.1799012700),
        from_demo(0.0317550858, 0.3630878276, 0.2672965075, 2.3050383959)};
    for (size_t k = 0; k < expected.size(); ++k) {
      x = euler(x, 0.0);
      EXPECT_TRUE(testing::MatricesNear(x, expected[k], 2e-10, 0)) << "fall step " << k;
    }
  }
}

// PILCO's convention: from hanging, a positive force accelerates the cart in
// +s and swings the pole to negative beta.
TEST(CartPoleTest, PositiveForceFromHangingMovesCartPositive) {
  const CartPole plant;
  const State d = plant.Derivative(State::Zero(), 10.0);
  EXPECT_GT(d(2), 0.0);
  EXPECT_LT(d(3), 0.0);
  State next;
  TG_ASSERT_OK(plant.Step(State::Zero(), 10.0, &next));
  EXPECT_GT(next(0), 0.0);
  EXPECT_GT(next(2), 0.0);
  EXPECT_LT(next(1), 0.0);
  EXPECT_LT(next(3), 0.0);
}

TEST(CartPoleTest, MirrorSymmetry) {
  // Reflecting the world (s, beta, f) -> (-s, -beta, -f) reflects the motion.
  const CartPole plant;
  for (const State& x : {MakeState(0.3, 0.7, -1.2, 4.0), MakeState(-1.0, 2.9, 0.5, -9.0)}) {
    EXPECT_TRUE(
        testing::MatricesNear(plant.Derivative(-x, -3.0), -plant.Derivative(x, 3.0), 1e-13, 0));
  }
}

TEST(CartPoleTest, EnergyRateIsPowerOfForceAndFriction) {
  // dE/dt = grad E . f(x, u) must equal (u - b s_dot) s_dot: the only
  // external work is the applied force and the cart friction. Ties Energy()
  // and Derivative() together at arbitrary states.
  const CartPole plant;
  const diff::VectorFunction energy = [&](const Vector& x, Vector* value) {
    *value = Vector::Constant(1, plant.Energy(State(x)));
    return true;
  };
  for (const State& x : {MakeState(0.1, 0.4, 0.8, -2.0), MakeState(-0.5, 3.5, -1.5, 7.0),
                         MakeState(2.0, -8.0, 3.0, 12.0)}) {
    for (double force : {0.0, 7.5, -10.0}) {
      Matrix grad;
      ASSERT_TRUE(diff::NumericJacobian(energy, x, 1e-6, &grad));
      const double rate = (grad * plant.Derivative(x, force))(0);
      const double power = (force - plant.params().friction * x(2)) * x(2);
      EXPECT_NEAR(rate, power, 1e-7 * (1.0 + std::abs(power))) << x.transpose() << " f " << force;
    }
  }
}

TEST(CartPoleTest, EnergyConservedWithoutFrictionAndForce) {
  CartPoleParams params;
  params.friction = 0.0;
  const CartPole plant(params);
  double worst = 0;
  for (const State& start : {MakeState(0.2, 2.0, 0.5, 1.0), MakeState(0.0, 0.3, 3.0, 14.0)}) {
    const double e0 = plant.Energy(start);
    ASSERT_GT(std::abs(e0), 0.1);  // so the relative drift is meaningful
    State x = start;
    for (int k = 0; k < 30; ++k) {  // 3 s
      State next;
      TG_ASSERT_OK(plant.Step(x, 0.0, &next));
      x = next;
      const double drift = std::abs(plant.Energy(x) - e0) / std::abs(e0);
      worst = std::max(worst, drift);
      EXPECT_LT(drift, 1e-8) << "step " << k << " from " << start.transpose();
    }
  }
  std::printf("energy: worst relative drift over 3 s = %.3g\n", worst);
}

TEST(CartPoleTest, StepMatchesFineRk4) {
  const CartPole plant;
  double worst = 0;
  for (const State& x : {State::Zero().eval(), MakeState(0.5, kPi - 0.2, -1.0, 3.0),
                         MakeState(-0.3, 1.0, 2.0, -14.0), MakeState(1.0, 10.0, -3.0, 9.0)}) {
    for (double force : {0.0, 10.0, -10.0, 3.3}) {
      State next;
      TG_ASSERT_OK(plant.Step(x, force, &next));
      Vector reference = x;
      const ode::Rhs rhs = [&](const Vector& z, Vector* dzdt) {
        *dzdt = plant.Derivative(State(z), force);
      };
      ode::IntegrateRk4(rhs, plant.params().dt, 2000, &reference);
      const double diff = (next - reference).lpNorm<Eigen::Infinity>();
      worst = std::max(worst, diff);
      EXPECT_LT(diff, 1e-9) << "from " << x.transpose() << " force " << force;
    }
  }
  std::printf("step: worst |adaptive - rk4(2000)| = %.3g\n", worst);
}

TEST(CartPoleTest, StepRejectsNonFiniteInputAndLeavesNextUnchanged) {
  const CartPole plant;
  const State sentinel = MakeState(7, 7, 7, 7);
  State next = sentinel;
  EXPECT_EQ(plant.Step(MakeState(0, std::nan(""), 0, 0), 0.0, &next).code(),
            absl::StatusCode::kInvalidArgument);
  EXPECT_EQ(next, sentinel);
  EXPECT_EQ(plant.Step(State::Zero(), std::numeric_limits<double>::infinity(), &next).code(),
            absl::StatusCode::kInvalidArgument);
  EXPECT_EQ(next, sentinel);
}

TEST(CartPoleTest, StepReportsIntegratorFailure) {
  CartPoleParams params;
  params.integrator.max_steps = 2;
  const CartPole plant(params);
  const State sentinel = MakeState(7, 7, 7, 7);
  State next = sentinel;
  ode::IntegrationReport report;
  const absl::Status st = plant.Step(MakeState(0, 1, 0, 5), 10.0, &next, &report);
  EXPECT_EQ(st.code(), absl::StatusCode::kResourceExhausted) << st;
  EXPECT_NE(st.message().find("cart-pole step"), std::string::npos) << st;
  EXPECT_EQ(next, sentinel);
  EXPECT_EQ(report.accepted_steps + report.rejected_steps, 2);
}

}  // namespace cartpole_test
}  // namespace totalgrad::tasks
