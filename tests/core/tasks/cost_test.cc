#include "core/tasks/cost.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <limits>
#include <numbers>
#include <random>
#include <vector>

#include "core/common/rng.h"
#include "core/diff/gradient_checker.h"
#include "core/gaussian/trig.h"
#include "core/tasks/scene.h"
#include "core/tasks/scene_catalog.h"
#include "tests/core/pilco/pilco_test_util.h"
#include "tests/testutil/testutil.h"

namespace totalgrad::tasks {
namespace cost_test {

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

}  // namespace cost_test
}  // namespace totalgrad::tasks

namespace totalgrad::tasks {
namespace cost_test {

// PILCO's saturating cost on z, on every scene of the catalog: gradients
// against finite differences (two angles, two widths included); the cart-pole's
// equals the tip cost; a wrong chain rule through sin/cos fails.
TEST(SaturatingCostTest, GradientsMatchFiniteDifferencesOnEveryScene) {
  for (const SceneDefinition& s : SceneCatalog()) {
    if (s.cost_kind != "saturating") continue;  // the unicycle's: unicycle_test.cc
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

// Every scene's saturating cost, as a trial builds it (tasks::MakeScene with
// cost = saturating), has PILCO's closed form: at a near-deterministic state
// it is the cost there (two angles included). One-angle and angle-free costs
// keep the bits of the one-angle overload they used before several angles
// were wired in (the PILCO trials and the cart-pole are pinned to them).
TEST(SaturatingCostTest, EverySceneHasTheClosedForm) {
  int several = 0;
  for (const SceneDefinition& s : SceneCatalog()) {
    // The unicycle's only cost is loss_unicycle (unicycle_test.cc).
    if (s.cost_kind != "saturating") continue;
    SceneOptions options;
    options.scene = s.name;
    options.cost = "saturating";
    absl::StatusOr<Scene> scene = MakeScene(options);
    ASSERT_TRUE(scene.ok()) << s.name << ": " << scene.status();
    ASSERT_EQ(scene->cost->Name(), "saturating") << s.name;
    absl::StatusOr<gaussian::GaussianCost> closed = scene->cost->GaussianExpectation();
    ASSERT_TRUE(closed.ok()) << s.name << ": " << closed.status();
    Vector x = s.target;
    for (Eigen::Index i = 0; i < x.size(); ++i) x(i) += 0.3 * static_cast<double>(i + 1);
    const Matrix tiny = 1e-14 * Matrix::Identity(x.size(), x.size());
    gaussian::CostMoments moments;
    ASSERT_TRUE(closed->Evaluate(x, tiny, true, &moments).ok());
    EXPECT_NEAR(moments.mean, scene->cost->Value(x), 1e-9) << s.name;
    if (s.angle_indices.size() > 1) {
      ++several;
      continue;
    }
    // The one-angle (or angle-free) overload, as the cost called it before.
    Vector target_z(s.saturating_cost.q.rows());
    target_z.head(s.state_dim()) = s.target;
    for (size_t a = 0; a < s.angle_indices.size(); ++a) {
      target_z(s.state_dim() + 2 * a) = std::sin(s.target(s.angle_indices[a]));
      target_z(s.state_dim() + 2 * a + 1) = std::cos(s.target(s.angle_indices[a]));
    }
    absl::StatusOr<gaussian::GaussianCost> before = gaussian::GaussianCost::Saturating(
        s.state_dim(), s.angle_indices.empty() ? -1 : s.angle_indices[0], s.saturating_cost.q,
        target_z, s.saturating_cost.widths);
    ASSERT_TRUE(before.ok()) << before.status();
    std::mt19937_64 rng(41);
    const Matrix cov = pilco::testing::RandomCovariance(s.state_dim(), 0.05, &rng);
    gaussian::CostMoments now, then;
    ASSERT_TRUE(closed->Evaluate(x, cov, true, &now).ok());
    ASSERT_TRUE(before->Evaluate(x, cov, true, &then).ok());
    EXPECT_EQ(now.mean, then.mean) << s.name;
    EXPECT_EQ(now.var, then.var) << s.name;
    EXPECT_EQ(now.dmean_dm, then.dmean_dm) << s.name;
    EXPECT_EQ(now.dmean_dS, then.dmean_dS) << s.name;
  }
  EXPECT_EQ(several, 3);  // the cart-double-pendulum, the double pendulum, the pendubot
}

// The several-angle scenes' saturating cost as trials use it (the scene's
// Q, widths and target from the catalog, through MakeScene and
// GaussianExpectation), at a Gaussian state near the target with correlated
// angles:
//  * the Gaussian it is evaluated on is z's exact mean and covariance under
//    x ~ N(m, S) (Monte Carlo of z = [x, sin, cos, ...] built here);
//  * its mean and variance are those of lossSat on that Gaussian of z
//    (Monte Carlo with the cost written out here from the catalog's
//    numbers: PILCO's mean over widths, variance the mean of the widths');
//  * its gradient with respect to the mean and covariance matches central
//    differences, and one that drops the two angles' covariance entry (the
//    pair moments' share) is rejected.
// The exact E[c(x)] differs from PILCO's (the Gaussian approximation of z);
// the gap is printed, not asserted.
TEST(SaturatingCostTest, SeveralAngleScenesGaussianExpectationMatchesMonteCarloAndDifferences) {
  constexpr int kSamples = 1000000;
  constexpr int kBatch = 100000;
  constexpr double kSigmas = 5.0;
  int checked = 0;
  for (const SceneDefinition& s : SceneCatalog()) {
    if (s.angle_indices.size() < 2) continue;
    SCOPED_TRACE(s.name);
    SceneOptions options;
    options.scene = s.name;
    options.cost = "saturating";
    absl::StatusOr<Scene> scene = MakeScene(options);
    ASSERT_TRUE(scene.ok()) << scene.status();
    absl::StatusOr<gaussian::GaussianCost> closed = scene->cost->GaussianExpectation();
    ASSERT_TRUE(closed.ok()) << closed.status();
    const int d = s.state_dim();
    const int nz = d + 2 * static_cast<int>(s.angle_indices.size());
    std::mt19937_64 rng(50 + checked);
    // Near the target (the cost neither 0 nor saturated at 1), each entry up
    // to 0.3 off with a std of ~0.15, the angles correlated through S.
    Vector m = s.target;
    for (int i = 0; i < d; ++i) m(i) += 0.3 * std::cos(1.0 + i);
    const Matrix cov = pilco::testing::RandomCovariance(d, 0.02, &rng);
    const int a1 = s.angle_indices[0], a2 = s.angle_indices[1];
    ASSERT_GT(std::abs(cov(a1, a2)), 1e-3);  // correlated angles: the pair blocks matter
    gaussian::CostMoments cm;
    ASSERT_TRUE(closed->Evaluate(m, cov, true, &cm).ok());
    EXPECT_GT(cm.mean, 0.05);
    EXPECT_LT(cm.mean, 0.95);
    EXPECT_GT(cm.var, 1e-3);

    // z of a batch of states, written out here from the definition of z.
    const auto features = [&](const RowMatrix& x) {
      RowMatrix z(x.rows(), nz);
      z.leftCols(d) = x;
      for (size_t a = 0; a < s.angle_indices.size(); ++a) {
        z.col(d + 2 * a) = x.col(s.angle_indices[a]).array().sin();
        z.col(d + 2 * a + 1) = x.col(s.angle_indices[a]).array().cos();
      }
      return z;
    };
    Vector target_z(nz);
    {
      RowMatrix t(1, d);
      t.row(0) = s.target.transpose();
      target_z = features(t).row(0).transpose();
    }
    // z's moments under x ~ N(m, S): what the closed form's Gaussian must be.
    Vector zm;
    Matrix zs;
    gaussian::AugmentWithTrig(m, cov, s.angle_indices, &zm, &zs);
    const pilco::testing::GaussianSampler x_sampler(m, cov);
    pilco::testing::MomentAccumulator z_acc(nz);
    z_acc.SetShift(zm);
    Vector exact_cost_sum = Vector::Zero(1);
    for (int done = 0; done < kSamples; done += kBatch) {
      const RowMatrix x = x_sampler.Sample(kBatch, &rng);
      z_acc.AddBatch(features(x));
      Vector c;
      scene->cost->Evaluate(x, &c, nullptr);
      exact_cost_sum(0) += c.sum();
    }
    EXPECT_TRUE(pilco::testing::WithinMcError(zm, z_acc.Mean(), z_acc.MeanStdError(), kSigmas));
    EXPECT_TRUE(pilco::testing::WithinMcError(zs, z_acc.Cov(), z_acc.CovStdError(), kSigmas));

    // lossSat on N(zm, zs), per width, the cost written out.
    const pilco::testing::GaussianSampler z_sampler(zm, zs);
    const std::vector<double>& widths = s.saturating_cost.widths;
    const Matrix& q = s.saturating_cost.q;
    double mean_of_means = 0, mean_of_vars = 0;
    std::vector<pilco::testing::MomentAccumulator> acc(widths.size(),
                                                       pilco::testing::MomentAccumulator(1));
    for (auto& a : acc) a.SetShift(Vector::Constant(1, cm.mean));
    for (int done = 0; done < kSamples; done += kBatch) {
      const RowMatrix z = z_sampler.Sample(kBatch, &rng);
      const RowMatrix dz = z.rowwise() - target_z.transpose();
      const Vector quad = (dz * q).cwiseProduct(dz).rowwise().sum();
      for (size_t k = 0; k < widths.size(); ++k) {
        const double w = widths[k];
        acc[k].AddBatch((1.0 - (-0.5 * quad.array() / (w * w)).exp()).matrix());
      }
    }
    double mean_se = 0, var_se = 0;
    for (size_t k = 0; k < widths.size(); ++k) {
      mean_of_means += acc[k].Mean()(0) / widths.size();
      mean_of_vars += acc[k].Cov()(0, 0) / widths.size();
      mean_se += acc[k].MeanStdError()(0) / widths.size();  // an upper bound for the mean's
      var_se += acc[k].CovStdError()(0, 0) / widths.size();
    }
    EXPECT_NEAR(cm.mean, mean_of_means, kSigmas * mean_se);
    EXPECT_NEAR(cm.var, mean_of_vars, kSigmas * var_se);
    std::printf("  %s: E[c] closed form %.5f, Monte Carlo on z's Gaussian %.5f +- %.1g; "
                "exact E[c(x)] %.5f (PILCO's Gaussian approximation of z); Var %.5f vs %.5f\n",
                s.name.c_str(), cm.mean, mean_of_means, mean_se, exact_cost_sum(0) / kSamples,
                cm.var, mean_of_vars);

    // Gradient with respect to (m, S), S through its lower triangle.
    const pilco::testing::BlockForward fwd = [&](const Vector& mm, const Matrix& ss, const Vector&,
                                                 Vector* y) {
      gaussian::CostMoments c;
      if (!closed->Evaluate(mm, ss, false, &c).ok()) return false;
      *y = Vector::Constant(1, c.mean);
      return true;
    };
    const auto backward = [&](bool drop_pair) -> pilco::testing::BlockBackward {
      return [&, drop_pair](const Vector& mm, const Matrix& ss, const Vector&, const Vector& yb,
                            Vector* mb, Matrix* sb, Vector*) {
        gaussian::CostMoments c;
        if (!closed->Evaluate(mm, ss, true, &c).ok()) return false;
        *mb = yb(0) * c.dmean_dm;
        *sb = yb(0) * c.dmean_dS;
        if (drop_pair) (*sb)(a1, a2) = (*sb)(a2, a1) = 0.0;
        return true;
      };
    };
    diff::CheckOptions tight;
    tight.relative_step = 1e-6;
    tight.relative_tolerance = 1e-6;
    tight.absolute_tolerance = 1e-8;
    const diff::CheckResult right =
        pilco::testing::CheckBlock(fwd, backward(false), m, cov, Vector(), tight);
    EXPECT_TRUE(right.ok) << right.log;
    ASSERT_GT(std::abs(cm.dmean_dS(a1, a2)), 1e-4);
    EXPECT_FALSE(pilco::testing::CheckBlock(fwd, backward(true), m, cov, Vector(), tight).ok);
    ++checked;
  }
  EXPECT_EQ(checked, 3);
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

}  // namespace cost_test
}  // namespace totalgrad::tasks
