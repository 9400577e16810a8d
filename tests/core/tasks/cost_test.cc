#include "core/tasks/cost.h"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <numbers>

#include "core/common/rng.h"
#include "core/diff/gradient_checker.h"
#include "core/tasks/scene_catalog.h"
#include "tests/testutil/testutil.h"

namespace totalgrad::tasks {
namespace {

constexpr double kPi = std::numbers::pi;

State MakeState(double s, double beta, double s_dot, double beta_dot) {
  State x;
  x << s, beta, s_dot, beta_dot;
  return x;
}

const State kUpright = MakeState(0, kPi, 0, 0);

std::unique_ptr<StateCost> Make(const std::string& name, const State& target = kUpright) {
  absl::StatusOr<std::unique_ptr<StateCost>> cost = MakeCost(name, target);
  EXPECT_TRUE(cost.ok()) << cost.status();
  return cost.ok() ? *std::move(cost) : nullptr;
}

TEST(AngleCostTest, KnownValues) {
  const std::unique_ptr<StateCost> cost = Make("angle");
  ASSERT_NE(cost, nullptr);
  EXPECT_EQ(cost->Name(), "angle");
  EXPECT_EQ(cost->Value(kUpright), 0.0);
  // Hanging at rest: (beta - pi)^2 = pi^2 with Q = diag(1, 1, 0, 0).
  EXPECT_NEAR(cost->Value(State::Zero()), 1.0 - std::exp(-kPi * kPi), 1e-15);
  // Velocities carry no weight; 1 m off target costs 1 - e^-1.
  EXPECT_NEAR(cost->Value(MakeState(1.0, kPi, 5.0, -5.0)), 1.0 - std::exp(-1.0), 1e-15);
  // Angles are never wrapped: one full turn past upright is far from target.
  EXPECT_NEAR(cost->Value(MakeState(0, 3 * kPi, 0, 0)), 1.0 - std::exp(-4 * kPi * kPi), 1e-15);
  // Non-default weights and target.
  const AngleCost weighted(MakeState(0.5, kPi, 0, 0), MakeState(0.5, 2.0, 0.1, 0));
  // q = 0.5 * 0.25 + 2 * 0.01 + 0.1 * 4 = 0.545.
  EXPECT_NEAR(weighted.Value(MakeState(0.0, kPi + 0.1, 2.0, 7.0)), 1.0 - std::exp(-0.545), 1e-15);
}

TEST(TipCostTest, KnownValues) {
  const std::unique_ptr<StateCost> cost = Make("tip");
  ASSERT_NE(cost, nullptr);
  EXPECT_EQ(cost->Name(), "tip");
  // Upright over the target: d = 0 (up to sin(pi) ~ 1e-16).
  EXPECT_NEAR(cost->Value(kUpright), 0.0, 1e-15);
  // Hanging at rest: d^2 = 4 l^2 = 1, cost 1 - exp(-1 / (2 * 0.25^2)) = 1 - e^-8.
  EXPECT_NEAR(cost->Value(State::Zero()), 1.0 - std::exp(-8.0), 1e-15);
  EXPECT_NEAR(cost->Value(State::Zero()), 0.99966, 5e-6);
  // Horizontal pole (beta = pi/2): tip at (0.5, 0), target tip at (0, 0.5), d^2 = 0.5.
  EXPECT_NEAR(cost->Value(MakeState(0, kPi / 2, 0, 0)), 1.0 - std::exp(-4.0), 1e-15);
  // Upright but the cart 0.25 m off: d = width, cost 1 - e^-0.5.
  EXPECT_NEAR(cost->Value(MakeState(0.25, kPi, 3.0, 3.0)), 1.0 - std::exp(-0.5), 1e-15);
  // The tip is periodic in beta, unlike the angle cost.
  EXPECT_NEAR(cost->Value(MakeState(0, 3 * kPi, 0, 0)), 0.0, 1e-14);
  // Target position comes from the target state.
  const std::unique_ptr<StateCost> shifted = Make("tip", MakeState(1.0, kPi, 0, 0));
  ASSERT_NE(shifted, nullptr);
  EXPECT_NEAR(shifted->Value(MakeState(1.0, kPi, 0, 0)), 0.0, 1e-15);
  EXPECT_NEAR(shifted->Value(kUpright), 1.0 - std::exp(-8.0), 1e-15);
}

// Batch of states that covers both costs' regimes: near target, hanging,
// far away, several turns of beta.
RowMatrix TestStates() {
  Rng rng(17, Stream::kEvaluation);
  RowMatrix x(12, 4);
  rng.FillNormal(&x);
  x.col(1) = x.col(1) * 2.0 + Vector::Constant(12, kPi);
  x.row(0) = kUpright.transpose() + RowMatrix::Constant(1, 4, 0.05);
  x.row(1) = State::Zero().transpose();
  x.row(2) = MakeState(0.3, -7.0, 1.0, 2.0).transpose();
  return x;
}

void ExpectGradientsMatchFiniteDifferences(const StateCost& cost) {
  const RowMatrix x = TestStates();
  Vector values;
  RowMatrix grad;
  cost.Evaluate(x, &values, &grad);
  ASSERT_EQ(values.size(), x.rows());
  ASSERT_EQ(grad.rows(), x.rows());
  ASSERT_EQ(grad.cols(), 4);
  const diff::VectorFunction f = [&](const Vector& z, Vector* value) {
    *value = Vector::Constant(1, cost.Value(State(z)));
    return true;
  };
  for (Eigen::Index i = 0; i < x.rows(); ++i) {
    const Vector xi = x.row(i).transpose();
    const diff::CheckResult check = diff::CheckJacobian(f, xi, grad.row(i));
    EXPECT_TRUE(check.ok) << cost.Name() << " row " << i << ": " << check.log;
  }
}

TEST(CostGradientTest, AngleCostMatchesFiniteDifferences) {
  ExpectGradientsMatchFiniteDifferences(*Make("angle"));
  ExpectGradientsMatchFiniteDifferences(
      AngleCost(MakeState(0.5, kPi, -0.2, 0.1), MakeState(0.5, 2.0, 0.1, 0.3)));
}

TEST(CostGradientTest, TipCostMatchesFiniteDifferences) {
  ExpectGradientsMatchFiniteDifferences(*Make("tip"));
  ExpectGradientsMatchFiniteDifferences(TipCost(0.4, 0.6, 0.5));
}

TEST(CostGradientTest, WrongGradientFailsTheCheck) {
  // The check must be able to fail: a tip-cost gradient with the cos-term of
  // d(d^2)/dbeta dropped, and an angle-cost gradient off by 1 %.
  const State x = MakeState(0.2, 2.5, 0.0, 0.0);
  for (const std::string name : {"tip", "angle"}) {
    const std::unique_ptr<StateCost> cost = Make(name);
    RowMatrix batch = x.transpose();
    Vector value;
    RowMatrix grad;
    cost->Evaluate(batch, &value, &grad);
    const diff::VectorFunction f = [&](const Vector& z, Vector* v) {
      *v = Vector::Constant(1, cost->Value(State(z)));
      return true;
    };
    ASSERT_TRUE(diff::CheckJacobian(f, x, grad).ok) << name;
    RowMatrix wrong = grad;
    if (name == "tip") {
      const double l = 0.5, w2 = 0.0625;
      const double dx = x(0) + l * std::sin(x(1));
      const double e = 1.0 - value(0);
      wrong(0, 1) -= e / (2 * w2) * 2.0 * dx * l * std::cos(x(1));
    } else {
      wrong *= 1.01;
    }
    EXPECT_FALSE(diff::CheckJacobian(f, x, wrong).ok) << name;
  }
}

TEST(CostBatchTest, BatchMatchesSingleStatesAndStaysInUnitInterval) {
  const RowMatrix x = TestStates();
  for (const std::string name : {"angle", "tip"}) {
    const std::unique_ptr<StateCost> cost = Make(name);
    Vector with_grad, without_grad;
    RowMatrix grad;
    cost->Evaluate(x, &with_grad, &grad);
    cost->Evaluate(x, &without_grad, nullptr);
    ASSERT_EQ(with_grad.size(), x.rows());
    EXPECT_EQ(with_grad, without_grad) << name;
    for (Eigen::Index i = 0; i < x.rows(); ++i) {
      EXPECT_EQ(with_grad(i), cost->Value(State(x.row(i).transpose()))) << name << " row " << i;
      EXPECT_GE(with_grad(i), 0.0);
      EXPECT_LE(with_grad(i), 1.0);
    }
    EXPECT_TRUE(grad.allFinite());
    // An empty batch is allowed.
    Vector empty_cost;
    cost->Evaluate(RowMatrix(0, 4), &empty_cost, &grad);
    EXPECT_EQ(empty_cost.size(), 0);
    EXPECT_EQ(grad.rows(), 0);
  }
}

TEST(MakeCostTest, RejectsUnknownNameAndNonFiniteTarget) {
  absl::StatusOr<std::unique_ptr<StateCost>> bad = MakeCost("quadratic", kUpright);
  EXPECT_EQ(bad.status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_NE(bad.status().message().find("quadratic"), std::string::npos) << bad.status();
  bad = MakeCost("angle", MakeState(0, std::numeric_limits<double>::quiet_NaN(), 0, 0));
  EXPECT_EQ(bad.status().code(), absl::StatusCode::kInvalidArgument);
}

TEST(MakeCostTest, DefaultParameters) {
  absl::StatusOr<std::unique_ptr<StateCost>> angle = MakeCost("angle", kUpright);
  TG_ASSERT_OK(angle.status());
  const auto* a = dynamic_cast<const AngleCost*>(angle->get());
  ASSERT_NE(a, nullptr);
  EXPECT_EQ(a->q_diagonal(), MakeState(1, 1, 0, 0));
  EXPECT_EQ(a->target(), kUpright);
  absl::StatusOr<std::unique_ptr<StateCost>> tip = MakeCost("tip", kUpright);
  TG_ASSERT_OK(tip.status());
  const auto* t = dynamic_cast<const TipCost*>(tip->get());
  ASSERT_NE(t, nullptr);
  EXPECT_EQ(t->target_position(), 0.0);
  EXPECT_EQ(t->pendulum_length(), 0.5);
  EXPECT_EQ(t->width(), 0.25);
}

}  // namespace
}  // namespace totalgrad::tasks

namespace totalgrad::tasks {
namespace {

// PILCO's saturating cost on z, on every scene of the catalog: gradients
// against finite differences (two angles, two widths included); the cart-pole's
// equals the tip cost; a wrong chain rule through sin/cos fails.
TEST(SaturatingCostTest, GradientsMatchFiniteDifferencesOnEveryScene) {
  for (const SceneDefinition& s : SceneCatalog()) {
    for (const std::vector<double>& widths : {s.saturating_cost.widths, std::vector<double>{0.5, 1.5}}) {
      const SaturatingCost cost(s.target, s.angle_indices, s.saturating_cost.q, widths);
      Rng rng(23, Stream::kEvaluation);
      RowMatrix x(6, s.state_dim());
      rng.FillNormal(&x);
      for (int a : s.angle_indices) x.col(a) *= 2.0;
      x.row(0) = s.target.transpose();
      Vector values;
      RowMatrix grad;
      cost.Evaluate(x, &values, &grad);
      EXPECT_NEAR(values(0), 0.0, 1e-15) << s.name;
      const diff::VectorFunction f = [&](const Vector& z, Vector* v) {
        *v = Vector::Constant(1, cost.Value(z));
        return true;
      };
      for (Eigen::Index i = 0; i < x.rows(); ++i) {
        EXPECT_GE(values(i), 0.0);
        EXPECT_LE(values(i), 1.0);
        const diff::CheckResult check = diff::CheckJacobian(f, x.row(i).transpose(), grad.row(i));
        EXPECT_TRUE(check.ok) << s.name << " row " << i << ": " << check.log;
      }
      // The chain rule's sin/cos terms matter: dropping one fails.
      if (!s.angle_indices.empty()) {
        RowMatrix wrong = grad;
        const Eigen::Index row = 3;
        wrong(row, s.angle_indices[0]) *= -1.0;
        if (std::abs(grad(row, s.angle_indices[0])) > 1e-6) {
          EXPECT_FALSE(diff::CheckJacobian(f, x.row(row).transpose(), wrong.row(row)).ok) << s.name;
        }
      }
    }
  }
}

// Each one-angle scene's saturating cost has PILCO's closed form (its
// GaussianExpectation at a near-deterministic state is the cost there);
// several angles are refused by name.
TEST(SaturatingCostTest, OneAngleScenesHaveTheClosedFormSeveralAnglesAreRefused) {
  for (const SceneDefinition& s : SceneCatalog()) {
    const SaturatingCost cost(s.target, s.angle_indices, s.saturating_cost.q, s.saturating_cost.widths);
    absl::StatusOr<pilco::GaussianCost> closed = cost.GaussianExpectation();
    if (s.angle_indices.size() > 1) {
      EXPECT_FALSE(closed.ok()) << s.name;
      EXPECT_NE(closed.status().message().find("several angles"), std::string::npos)
          << closed.status();
      continue;
    }
    ASSERT_TRUE(closed.ok()) << s.name << ": " << closed.status();
    Vector x = s.target;
    for (Eigen::Index i = 0; i < x.size(); ++i) x(i) += 0.3 * static_cast<double>(i + 1);
    pilco::CostMoments moments;
    ASSERT_TRUE(closed->Evaluate(x, 1e-14 * Matrix::Identity(x.size(), x.size()), false,
                                 &moments).ok());
    EXPECT_NEAR(moments.mean, cost.Value(x), 1e-9) << s.name;
  }
}

TEST(SaturatingCostTest, CartPolesEqualsTheTipCost) {
  const SceneDefinition& s = *FindSceneDefinition("cartpole-swingup");
  const SaturatingCost saturating(s.target, s.angle_indices, s.saturating_cost.q, s.saturating_cost.widths);
  const TipCost tip(0.0, 0.5, 0.25);
  const RowMatrix x = TestStates();
  Vector a, b;
  saturating.Evaluate(x, &a, nullptr);
  tip.Evaluate(x, &b, nullptr);
  EXPECT_TRUE(testing::MatricesNear(a, b, 1e-14, 1e-12));
}

}  // namespace
}  // namespace totalgrad::tasks
