#include "core/ode/integrator.h"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>

#include "tests/testutil/testutil.h"

namespace totalgrad::ode {
namespace integrator_test {

constexpr double kInf = std::numeric_limits<double>::infinity();
constexpr double kNan = std::numeric_limits<double>::quiet_NaN();

// q' = p, p' = -w^2 q: q(t) = cos(w t), p(t) = -w sin(w t) from (1, 0).
Rhs Oscillator(double w) {
  return [w](const Vector& x, Vector* dxdt) {
    (*dxdt)(0) = x(1);
    (*dxdt)(1) = -w * w * x(0);
  };
}

// Large-amplitude pendulum theta'' = -sin(theta): nonlinear, no closed form.
void Pendulum(const Vector& x, Vector* dxdt) {
  (*dxdt)(0) = x(1);
  (*dxdt)(1) = -std::sin(x(0));
}

Vector Vec2(double a, double b) {
  Vector v(2);
  v << a, b;
  return v;
}

TEST(IntegrateAdaptiveTest, HarmonicOscillatorMeetsTolerance) {
  const double w = 2.0, duration = 10.0;
  IntegratorOptions options;  // 1e-10 relative and absolute
  Vector x = Vec2(1.0, 0.0);
  IntegrationReport report;
  TG_ASSERT_OK(IntegrateAdaptive(Oscillator(w), duration, options, &x, &report));
  const Vector exact = Vec2(std::cos(w * duration), -w * std::sin(w * duration));
  const double error = (x - exact).lpNorm<Eigen::Infinity>();
  // Each accepted step commits a local error of at most tol * (1 + |x| +
  // dt |x'|) <= tol * (1 + 2 + 4 dt) per component; the oscillator does not
  // amplify errors (its flow is a rotation after scaling), so the global
  // error is at most the sum of the local ones.
  const double bound = report.accepted_steps * options.relative_tolerance * 4.0;
  EXPECT_LE(error, bound) << "accepted " << report.accepted_steps;
  EXPECT_LT(error, 1e-7);
  EXPECT_GT(report.accepted_steps, 10);
  EXPECT_GT(report.smallest_step, 0.0);
  EXPECT_LE(report.smallest_step, duration);
  std::printf("oscillator: error %.3g with %d accepted, %d rejected steps\n", error,
              report.accepted_steps, report.rejected_steps);
}

TEST(IntegrateAdaptiveTest, ExponentialDecayErrorFollowsTolerance) {
  const Rhs decay = [](const Vector& x, Vector* dxdt) { *dxdt = -x; };
  const double duration = 3.0;
  const double exact = std::exp(-duration);
  double previous_error = kInf;
  for (double tol : {1e-6, 1e-8, 1e-10, 1e-12}) {
    IntegratorOptions options;
    options.relative_tolerance = options.absolute_tolerance = tol;
    Vector x = Vector::Constant(1, 1.0);
    IntegrationReport report;
    TG_ASSERT_OK(IntegrateAdaptive(decay, duration, options, &x, &report));
    const double error = std::abs(x(0) - exact);
    // The decay contracts errors, so the global error is below the sum of
    // the local tolerances (scale 1 + |x| + dt |x'| <= 3).
    EXPECT_LE(error, 3.0 * tol * report.accepted_steps) << "tol " << tol;
    // Tighter tolerance, smaller error (until rounding takes over).
    EXPECT_LT(error, previous_error) << "tol " << tol;
    previous_error = error;
  }
}

TEST(IntegrateAdaptiveTest, LandsExactlyOnDuration) {
  // x' = 1 from 0: x(T) = T, whatever steps the controller took.
  const Rhs clock = [](const Vector&, Vector* dxdt) { (*dxdt)(0) = 1.0; };
  for (double duration : {1e-6, 0.1, 0.123, 3.7}) {
    Vector x = Vector::Zero(1);
    IntegrationReport report;
    TG_ASSERT_OK(IntegrateAdaptive(clock, duration, {}, &x, &report));
    EXPECT_NEAR(x(0), duration, 8 * std::numeric_limits<double>::epsilon() * duration)
        << "duration " << duration;
  }
}

TEST(IntegrateAdaptiveTest, AgreesWithFineRk4OnNonlinearPendulum) {
  const double duration = 5.0;
  Vector reference = Vec2(3.0, 0.0);  // near the top: strongly nonlinear
  IntegrateRk4(Pendulum, duration, 50000, &reference);
  Vector x = Vec2(3.0, 0.0);
  TG_ASSERT_OK(IntegrateAdaptive(Pendulum, duration, {}, &x, nullptr));
  const double diff = (x - reference).lpNorm<Eigen::Infinity>();
  EXPECT_LT(diff, 1e-8);
  std::printf("pendulum: |adaptive - rk4(50000)| = %.3g\n", diff);
}

TEST(IntegrateRk4Test, FourthOrderConvergence) {
  const double w = 2.0, duration = 2.0;
  const Vector exact = Vec2(std::cos(w * duration), -w * std::sin(w * duration));
  double previous = 0;
  for (int n : {20, 40, 80, 160}) {
    Vector x = Vec2(1.0, 0.0);
    IntegrateRk4(Oscillator(w), duration, n, &x);
    const double error = (x - exact).lpNorm<Eigen::Infinity>();
    if (previous > 0) {
      // Halving h divides the error of a 4th-order method by 2^4 = 16.
      const double ratio = previous / error;
      EXPECT_GT(ratio, 14.0) << "n " << n;
      EXPECT_LT(ratio, 18.0) << "n " << n;
    }
    previous = error;
  }
}

TEST(IntegrateAdaptiveTest, StiffProblemExhaustsBudgetAndLeavesStateUnchanged) {
  // x' = -1e7 (x - 1): an explicit method needs steps of about 3e-7 s for
  // stability, i.e. millions over one second.
  const Rhs stiff = [](const Vector& x, Vector* dxdt) { (*dxdt)(0) = -1e7 * (x(0) - 1.0); };
  IntegratorOptions options;
  options.max_steps = 5000;
  Vector x = Vector::Constant(1, 0.0);
  IntegrationReport report;
  const absl::Status st = IntegrateAdaptive(stiff, 1.0, options, &x, &report);
  EXPECT_EQ(st.code(), absl::StatusCode::kResourceExhausted) << st;
  EXPECT_EQ(x(0), 0.0);
  EXPECT_EQ(report.accepted_steps + report.rejected_steps, options.max_steps);
}

TEST(IntegrateAdaptiveTest, TooSmallBudgetFails) {
  Vector x = Vec2(1.0, 0.0);
  IntegratorOptions options;
  options.max_steps = 3;
  const absl::Status st = IntegrateAdaptive(Oscillator(2.0), 10.0, options, &x, nullptr);
  EXPECT_EQ(st.code(), absl::StatusCode::kResourceExhausted) << st;
  EXPECT_EQ(x, Vec2(1.0, 0.0));
}

TEST(IntegrateAdaptiveTest, FiniteTimeBlowUpIsStepUnderflow) {
  // x' = x^2, x(0) = 1: x = 1 / (1 - t) is singular at t = 1 < duration.
  const Rhs blow_up = [](const Vector& x, Vector* dxdt) { (*dxdt)(0) = x(0) * x(0); };
  Vector x = Vector::Constant(1, 1.0);
  IntegrationReport report;
  const absl::Status st = IntegrateAdaptive(blow_up, 2.0, {}, &x, &report);
  EXPECT_EQ(st.code(), absl::StatusCode::kInternal) << st;
  EXPECT_NE(st.message().find("min_step"), std::string::npos) << st;
  EXPECT_EQ(x(0), 1.0);
  EXPECT_GT(report.rejected_steps, 0);
}

TEST(IntegrateAdaptiveTest, NonFiniteIntermediateStateIsInternal) {
  // The derivative turns NaN once x passes 0.5; odeint's error norm would not
  // notice (it skips NaN), so this checks our own finiteness test.
  const Rhs poisoned = [](const Vector& x, Vector* dxdt) {
    (*dxdt)(0) = x(0) > 0.5 ? kNan : 1.0;
  };
  Vector x = Vector::Zero(1);
  const absl::Status st = IntegrateAdaptive(poisoned, 1.0, {}, &x, nullptr);
  EXPECT_EQ(st.code(), absl::StatusCode::kInternal) << st;
  EXPECT_NE(st.message().find("non-finite"), std::string::npos) << st;
  EXPECT_EQ(x(0), 0.0);
}

TEST(IntegrateAdaptiveTest, NonFiniteDerivativeAtStartIsInternal) {
  const Rhs bad = [](const Vector&, Vector* dxdt) { (*dxdt)(0) = kInf; };
  Vector x = Vector::Zero(1);
  EXPECT_EQ(IntegrateAdaptive(bad, 1.0, {}, &x, nullptr).code(), absl::StatusCode::kInternal);
  EXPECT_EQ(x(0), 0.0);
}

TEST(IntegrateAdaptiveTest, NonFiniteStartIsInvalidArgumentAndStateUnchanged) {
  for (double bad : {kNan, kInf, -kInf}) {
    Vector x = Vec2(1.0, bad);
    const absl::Status st = IntegrateAdaptive(Oscillator(1.0), 1.0, {}, &x, nullptr);
    EXPECT_EQ(st.code(), absl::StatusCode::kInvalidArgument) << st;
    EXPECT_EQ(x(0), 1.0);
    EXPECT_EQ(std::isnan(x(1)), std::isnan(bad));
    if (!std::isnan(bad)) {
      EXPECT_EQ(x(1), bad);
    }
  }
}

TEST(IntegrateAdaptiveTest, BadDurationOrOptionsAreInvalidArgument) {
  Vector x = Vec2(1.0, 0.0);
  for (double duration : {0.0, -1.0, kNan, kInf}) {
    EXPECT_EQ(IntegrateAdaptive(Oscillator(1.0), duration, {}, &x, nullptr).code(),
              absl::StatusCode::kInvalidArgument)
        << duration;
  }
  IntegratorOptions no_tolerance;
  no_tolerance.relative_tolerance = no_tolerance.absolute_tolerance = 0;
  IntegratorOptions negative_step;
  negative_step.initial_step = -1e-3;
  IntegratorOptions no_budget;
  no_budget.max_steps = 0;
  IntegratorOptions nan_tolerance;
  nan_tolerance.relative_tolerance = kNan;
  for (const IntegratorOptions& o : {no_tolerance, negative_step, no_budget, nan_tolerance}) {
    EXPECT_EQ(IntegrateAdaptive(Oscillator(1.0), 1.0, o, &x, nullptr).code(),
              absl::StatusCode::kInvalidArgument);
  }
  EXPECT_EQ(x, Vec2(1.0, 0.0));
}

}  // namespace integrator_test
}  // namespace totalgrad::ode
