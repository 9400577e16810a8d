// The chained objective: J and dJ/dtheta over 30 steps against finite
// differences, symmetric PSD covariances at every step, and degenerate
// inputs (deterministic start, nearly singular sin/cos block, a policy and a
// state far from the data, a non-PSD covariance).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>
#include <vector>

#include <Eigen/Eigenvalues>

#include "core/diff/gradient_checker.h"
#include "core/gaussian/expected_cost.h"
#include "core/pilco/gp_moments.h"
#include "core/pilco/propagation.h"
#include "core/tasks/cartpole.h"
#include "core/tasks/scene.h"
#include "tests/core/pilco/pilco_test_util.h"
#include "tests/testutil/testutil.h"

namespace totalgrad::pilco {
namespace propagation_test {

// A GP on real cart-pole transitions (state [s, beta, s_dot, beta_dot]) with
// PILCO's initial hyperparameters (log l = log std(inputs), sf = std(targets),
// sn = sf / 10). angle_index 1: inputs [s, s_dot, beta_dot, sin, cos, u].
GaussianInputGp CartPoleGp(int n, bool sin_cos, uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> normal;
  std::uniform_real_distribution<double> uniform(-10, 10);
  const tasks::CartPole plant;
  const int e = sin_cos ? 6 : 5;
  RowMatrix x(n, e), y(n, 4);
  for (int i = 0; i < n; ++i) {
    tasks::State s(0.5 * normal(rng), 3.0 * normal(rng), 1.0 * normal(rng), 3.0 * normal(rng));
    const double u = uniform(rng);
    tasks::State next;
    EXPECT_TRUE(plant.Step(s, u, &next).ok());
    if (sin_cos) {
      x.row(i) << s(0), s(2), s(3), std::sin(s(1)), std::cos(s(1)), u;
    } else {
      x.row(i) << s(0), s(1), s(2), s(3), u;
    }
    y.row(i) = (next - s).transpose();
  }
  RowMatrix log_hyp(4, e + 2);
  for (int a = 0; a < 4; ++a) {
    for (int j = 0; j < e; ++j) {
      const double mean = x.col(j).mean();
      log_hyp(a, j) = std::log(std::sqrt((x.col(j).array() - mean).square().sum() / (n - 1)));
    }
    const double mean = y.col(a).mean();
    const double sd = std::sqrt((y.col(a).array() - mean).square().sum() / (n - 1));
    log_hyp(a, e) = std::log(sd);
    log_hyp(a, e + 1) = std::log(sd / 10);
  }
  auto gp = GaussianInputGpFromData(x, y, log_hyp);
  EXPECT_TRUE(gp.ok()) << gp.status();
  return *gp;
}

Vector InitialPolicy(const Propagator& prop, int num_basis, uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> normal;
  const int ep = prop.policy_input_dim();
  Vector p(prop.num_parameters());
  for (int k = 0; k < num_basis; ++k) {
    const Vector x = Eigen::Vector4d(0.1 * normal(rng), 0.1 * normal(rng), 0.1 * normal(rng),
                                     0.1 * normal(rng));
    p.segment(k * ep, ep) = prop.PolicyInput(x);
  }
  p.segment(num_basis * ep, ep).setConstant(std::log(1.0));
  if (ep == 5) p.segment(num_basis * ep + 3, 2).setConstant(std::log(0.7));
  for (int k = 0; k < num_basis; ++k) p(num_basis * ep + ep + k) = 0.1 * normal(rng);
  return p;
}

::testing::AssertionResult AllSymmetricPsd(const Trajectory& tr) {
  for (size_t t = 0; t < tr.covs.size(); ++t) {
    const Matrix& s = tr.covs[t];
    if (!s.allFinite()) return ::testing::AssertionFailure() << "step " << t << " not finite";
    if ((s - s.transpose()).cwiseAbs().maxCoeff() != 0.0) {
      return ::testing::AssertionFailure() << "step " << t << " not symmetric";
    }
    const double min_eig = Eigen::SelfAdjointEigenSolver<Matrix>(s).eigenvalues().minCoeff();
    if (min_eig < -1e-12 * (1.0 + s.cwiseAbs().maxCoeff())) {
      return ::testing::AssertionFailure() << "step " << t << " min eigenvalue " << min_eig;
    }
  }
  return ::testing::AssertionSuccess();
}

struct Scenario {
  bool sin_cos;
  const char* cost;  // "tip" or "angle"
};

class ChainedObjectiveTest : public ::testing::TestWithParam<Scenario> {};

TEST_P(ChainedObjectiveTest, GradientOver30StepsMatchesFiniteDifferences) {
  const Scenario sc = GetParam();
  const GaussianInputGp gp = CartPoleGp(60, sc.sin_cos, 21);
  PropagationOptions options;
  options.angle_index = sc.sin_cos ? 1 : -1;
  options.num_basis = 6;
  const Propagator prop(&gp, options);
  auto cost = std::string(sc.cost) == "tip"
                  ? gaussian::GaussianCost::Tip(4, 0, 1, 0.5, 0.25)
                  : gaussian::GaussianCost::Angle(Eigen::Vector4d(0, M_PI, 0, 0),
                                        Eigen::Vector4d(1, 1, 0, 0).asDiagonal().toDenseMatrix());
  ASSERT_TRUE(cost.ok());
  const Vector params = InitialPolicy(prop, 6, 22);
  const Vector mu0 = Vector::Zero(4);
  const Matrix s0 = 0.01 * Matrix::Identity(4, 4);
  Trajectory tr;
  Vector grad;
  ASSERT_TRUE(PredictTrajectory(prop, *cost, params, mu0, s0, 30, &tr, &grad).ok());
  EXPECT_TRUE(AllSymmetricPsd(tr));
  EXPECT_GT(tr.total_cost, 1.0);
  EXPECT_LT(tr.total_cost, 30.0);
  // The state distribution really moves (else the check is weak).
  EXPECT_GT(tr.covs[30].trace(), 10 * s0.trace());
  const diff::VectorFunction j = [&](const Vector& th, Vector* out) {
    Trajectory t;
    if (!PredictTrajectory(prop, *cost, th, mu0, s0, 30, &t, nullptr).ok()) return false;
    *out = Vector::Constant(1, t.total_cost);
    return true;
  };
  diff::CheckOptions check;
  check.relative_step = 1e-6;
  check.relative_tolerance = 1e-5;
  check.absolute_tolerance = 1e-7;
  const diff::CheckResult r = diff::CheckJacobian(j, params, grad.transpose(), check);
  EXPECT_TRUE(r.ok) << r.log;
  EXPECT_GT(grad.norm(), 1e-3);
  // A gradient with its largest entry wrong by 0.1 % fails the same criterion.
  Eigen::Index worst;
  grad.cwiseAbs().maxCoeff(&worst);
  const double wrong = grad(worst) * 1.001, numeric = r.numeric(0, worst);
  EXPECT_GT(std::abs(wrong - numeric),
            check.absolute_tolerance +
                check.relative_tolerance * std::max(std::abs(wrong), std::abs(numeric)));
}

INSTANTIATE_TEST_SUITE_P(Scenarios, ChainedObjectiveTest,
                         ::testing::Values(Scenario{true, "tip"}, Scenario{false, "angle"},
                                           Scenario{true, "angle"}));

// Two angles on the real cart-double-pendulum (state [x, dx, dtheta1,
// dtheta2, theta1, theta2], angles 4 and 5, GP and policy inputs [x, dx,
// dtheta1, dtheta2, sin th1, cos th1, sin th2, cos th2] (+ u), PILCO's initial
// hyperparameters), its start distribution and an angle cost's closed form:
// J and dJ/dtheta over 30 steps against finite differences.
TEST(ChainedObjectiveTwoAngles, CartDoublePendulumGradientMatchesFiniteDifferences) {
  tasks::SceneOptions so;
  so.scene = "cart-double-pendulum";
  absl::StatusOr<tasks::Scene> scene = tasks::MakeScene(so);
  ASSERT_TRUE(scene.ok()) << scene.status();
  const std::vector<int> angles = scene->angle_indices;
  ASSERT_EQ(angles, (std::vector<int>{4, 5}));
  const int d = 6, e = d + 2 + 1, n = 80;
  std::mt19937_64 rng(31);
  std::normal_distribution<double> normal;
  std::uniform_real_distribution<double> uniform(-20, 20);
  RowMatrix x(n, e), y(n, d);
  for (int i = 0; i < n; ++i) {
    Vector st(d);
    st << 0.3 * normal(rng), 0.5 * normal(rng), 2.0 * normal(rng), 2.0 * normal(rng),
        M_PI + 0.8 * normal(rng), M_PI + 0.8 * normal(rng);
    const double u = uniform(rng);
    Vector next;
    ASSERT_TRUE(scene->plant->Step(st, Vector::Constant(1, u), &next).ok());
    x.row(i) << st(0), st(1), st(2), st(3), std::sin(st(4)), std::cos(st(4)), std::sin(st(5)),
        std::cos(st(5)), u;
    y.row(i) = (next - st).transpose();
  }
  RowMatrix log_hyp(d, e + 2);
  for (int a = 0; a < d; ++a) {
    for (int j = 0; j < e; ++j) {
      const double mean = x.col(j).mean();
      log_hyp(a, j) = std::log(std::sqrt((x.col(j).array() - mean).square().sum() / (n - 1)));
    }
    const double mean = y.col(a).mean();
    const double sd = std::sqrt((y.col(a).array() - mean).square().sum() / (n - 1));
    log_hyp(a, e) = std::log(sd);
    log_hyp(a, e + 1) = std::log(sd / 10);
  }
  auto gp = GaussianInputGpFromData(x, y, log_hyp);
  ASSERT_TRUE(gp.ok()) << gp.status();
  PropagationOptions options;
  options.angle_indices = angles;
  options.num_basis = 6;
  options.max_force = scene->max_control(0);
  const Propagator prop(&*gp, options);
  // An angle cost towards a state near the start (the scene's, upright, is
  // ~1 everywhere near the hanging start: too flat a gradient to check).
  Vector target(d);
  target << 0.0, 0.0, 0.0, 0.0, M_PI - 0.5, M_PI + 0.5;
  Vector q(d);
  q << 1.0, 0.0, 0.0, 0.0, 1.0, 1.0;
  absl::StatusOr<gaussian::GaussianCost> cost = gaussian::GaussianCost::Angle(target, q.asDiagonal().toDenseMatrix());
  ASSERT_TRUE(cost.ok()) << cost.status();
  // Centres at the policy inputs of states around the start, log l = 0, the
  // (sin, cos) ones log 0.7, weights ~ N(0, 1).
  const int ep = prop.policy_input_dim();
  ASSERT_EQ(ep, 8);
  Vector params(prop.num_parameters());
  for (int k = 0; k < 6; ++k) {
    Vector c = scene->mu0;
    for (int m = 0; m < d; ++m) c(m) += 0.3 * normal(rng);
    params.segment(k * ep, ep) = prop.PolicyInput(c);
  }
  params.segment(6 * ep, ep).setZero();
  params.segment(6 * ep + 4, 4).setConstant(std::log(0.7));
  for (int k = 0; k < 6; ++k) params(6 * ep + ep + k) = normal(rng);
  const Matrix s0 = scene->initial_std.array().square().matrix().asDiagonal();
  Trajectory tr;
  Vector grad;
  ASSERT_TRUE(PredictTrajectory(prop, *cost, params, scene->mu0, s0, 30, &tr, &grad).ok());
  EXPECT_TRUE(AllSymmetricPsd(tr));
  EXPECT_GT(tr.covs[30].trace(), 10 * s0.trace()) << "the state distribution should move";
  const diff::VectorFunction j = [&](const Vector& th, Vector* out) {
    Trajectory t;
    if (!PredictTrajectory(prop, *cost, th, scene->mu0, s0, 30, &t, nullptr).ok()) return false;
    *out = Vector::Constant(1, t.total_cost);
    return true;
  };
  diff::CheckOptions check;
  check.relative_step = 1e-6;
  check.relative_tolerance = 1e-5;
  check.absolute_tolerance = 1e-7;
  const diff::CheckResult r = diff::CheckJacobian(j, params, grad.transpose(), check);
  EXPECT_TRUE(r.ok) << r.log;
  EXPECT_GT(grad.norm(), 1e-3);
}

// Two controls on the real double pendulum (state [dtheta1, dtheta2,
// theta1, theta2], angles 2 and 3, two torques; GP inputs [dth1, dth2, sin
// th1, cos th1, sin th2, cos th2, u1, u2], PILCO's initial hyperparameters):
// J and dJ/dtheta over 30 steps against finite differences.
TEST(ChainedObjectiveTwoControls, DoublePendulumGradientMatchesFiniteDifferences) {
  tasks::SceneOptions so;
  so.scene = "double-pendulum";
  absl::StatusOr<tasks::Scene> scene = tasks::MakeScene(so);
  ASSERT_TRUE(scene.ok()) << scene.status();
  ASSERT_EQ(scene->angle_indices, (std::vector<int>{2, 3}));
  ASSERT_EQ(scene->control_dim(), 2);
  const int d = 4, f = 2, e = d + 2 + f, n = 80;
  std::mt19937_64 rng(41);
  std::normal_distribution<double> normal;
  std::uniform_real_distribution<double> uniform(-2, 2);
  RowMatrix x(n, e), y(n, d);
  for (int i = 0; i < n; ++i) {
    Vector st(d);
    st << 2.0 * normal(rng), 2.0 * normal(rng), M_PI + 0.8 * normal(rng), M_PI + 0.8 * normal(rng);
    const Vector u = Eigen::Vector2d(uniform(rng), uniform(rng));
    Vector next;
    ASSERT_TRUE(scene->plant->Step(st, u, &next).ok());
    x.row(i) << st(0), st(1), std::sin(st(2)), std::cos(st(2)), std::sin(st(3)), std::cos(st(3)),
        u(0), u(1);
    y.row(i) = (next - st).transpose();
  }
  RowMatrix log_hyp(d, e + 2);
  for (int a = 0; a < d; ++a) {
    for (int j = 0; j < e; ++j) {
      const double mean = x.col(j).mean();
      log_hyp(a, j) = std::log(std::sqrt((x.col(j).array() - mean).square().sum() / (n - 1)));
    }
    const double mean = y.col(a).mean();
    const double sd = std::sqrt((y.col(a).array() - mean).square().sum() / (n - 1));
    log_hyp(a, e) = std::log(sd);
    log_hyp(a, e + 1) = std::log(sd / 10);
  }
  auto gp = GaussianInputGpFromData(x, y, log_hyp);
  ASSERT_TRUE(gp.ok()) << gp.status();
  PropagationOptions options;
  options.angle_indices = scene->angle_indices;
  options.num_basis = 6;
  options.max_controls = scene->max_control;
  const Propagator prop(&*gp, options);
  // An angle cost towards a state near the start (see the two-angle test).
  Vector target(d);
  target << 0.0, 0.0, M_PI - 0.5, M_PI + 0.5;
  Vector q(d);
  q << 0.0, 0.0, 1.0, 1.0;
  absl::StatusOr<gaussian::GaussianCost> cost = gaussian::GaussianCost::Angle(target, q.asDiagonal().toDenseMatrix());
  ASSERT_TRUE(cost.ok()) << cost.status();
  const int ep = prop.policy_input_dim();
  ASSERT_EQ(ep, 6);
  Vector params(prop.num_parameters());
  ASSERT_EQ(params.size(), 6 * ep + ep + 6 * f);
  for (int k = 0; k < 6; ++k) {
    Vector c = scene->mu0;
    for (int m = 0; m < d; ++m) c(m) += 0.3 * normal(rng);
    params.segment(k * ep, ep) = prop.PolicyInput(c);
  }
  params.segment(6 * ep, ep).setZero();
  params.segment(6 * ep + 2, 4).setConstant(std::log(0.7));
  for (int k = 0; k < 6 * f; ++k) params(6 * ep + ep + k) = normal(rng);
  const Matrix s0 = scene->initial_std.array().square().matrix().asDiagonal();
  Trajectory tr;
  Vector grad;
  ASSERT_TRUE(PredictTrajectory(prop, *cost, params, scene->mu0, s0, 30, &tr, &grad).ok());
  EXPECT_TRUE(AllSymmetricPsd(tr));
  EXPECT_GT(tr.covs[30].trace(), 10 * s0.trace()) << "the state distribution should move";
  const diff::VectorFunction j = [&](const Vector& th, Vector* out) {
    Trajectory t;
    if (!PredictTrajectory(prop, *cost, th, scene->mu0, s0, 30, &t, nullptr).ok()) return false;
    *out = Vector::Constant(1, t.total_cost);
    return true;
  };
  diff::CheckOptions check;
  check.relative_step = 1e-6;
  check.relative_tolerance = 1e-5;
  check.absolute_tolerance = 1e-7;
  const diff::CheckResult r = diff::CheckJacobian(j, params, grad.transpose(), check);
  EXPECT_TRUE(r.ok) << r.log;
  // Both torques' pseudo-weights carry gradient.
  for (int jj = 0; jj < f; ++jj) {
    double largest = 0;
    for (int k = 0; k < 6; ++k) largest = std::max(largest, std::abs(grad(6 * ep + ep + k * f + jj)));
    EXPECT_GT(largest, 1e-4) << "torque " << jj;
  }
}

// PILCO's general index sets (poli, dyni into z = [x, sin, cos per angle]):
// two angles, a GP that sees a state dim the policy does not and the policy
// a sin/cos pair ordered differently from the default, one and two
// controls, and the several-angle saturating cost on z. J over 15 steps and
// dJ/dtheta against central differences; every covariance symmetric PSD.
// The third case gives the policy one row of length-scales per control
// (PILCO's per-output gp2 hyperparameters; RbfPolicyShape::
// lengthscale_per_control), whose gradient comes from
// PredictGaussianLengthscaleAdjoint and the unscaled gp2.
struct SeparateCase {
  int controls;
  bool per_control_lengthscales;
};
class SeparateInputsTest : public ::testing::TestWithParam<SeparateCase> {};

TEST_P(SeparateInputsTest, GradientMatchesFiniteDifferences) {
  const int f = GetParam().controls;
  const bool per_control = GetParam().per_control_lengthscales;
  const int d = 4;
  const std::vector<int> angles = {1, 3};  // z = [x0..x3, s1, c1, s3, c3] (8)
  const std::vector<int> poli = {0, 2, 4, 5, 6, 7};
  const std::vector<int> dyni = {0, 2, 3, 4, 5, 6, 7};  // also the raw angle x3
  std::mt19937_64 rng(51 + f);
  const GaussianInputGp gp =
      testing::MakeTestGp(40, static_cast<int>(dyni.size()) + f, d, &rng, 1.5);
  PropagationOptions options;
  options.angle_indices = angles;
  options.policy_inputs = poli;
  options.dynamics_inputs = dyni;
  options.num_basis = 5;
  if (f > 1) options.max_controls = Eigen::Vector2d(2.0, 3.0);
  else options.max_force = 2.5;
  options.policy_lengthscale_per_control = per_control;
  ASSERT_TRUE(Propagator::Validate(gp, options).ok()) << Propagator::Validate(gp, options);
  const Propagator prop(&gp, options);
  ASSERT_EQ(prop.policy_input_dim(), 6);
  const int ep = 6, c = 5, rows = per_control ? f : 1;
  ASSERT_EQ(prop.num_parameters(), c * ep + rows * ep + c * f);
  std::normal_distribution<double> normal;
  Vector params(prop.num_parameters());
  const Vector mu0 = Eigen::Vector4d(0.1, 0.4, -0.2, 2.8);
  for (int k = 0; k < c; ++k) {
    Vector x = mu0;
    for (int m = 0; m < d; ++m) x(m) += 0.3 * normal(rng);
    params.segment(k * ep, ep) = prop.PolicyInput(x);
  }
  params.segment(c * ep, rows * ep) = testing::RandomVector(rows * ep, 0.3, &rng);
  for (int k = 0; k < c * f; ++k) params(c * ep + rows * ep + k) = normal(rng);
  const Matrix s0 = 0.05 * Matrix::Identity(d, d);
  const Matrix q = testing::RandomCovariance(8, 0.5, &rng);
  Vector zt = Vector::Zero(8);
  zt(6) = 0.0;
  zt(7) = -1.0;
  auto cost = gaussian::GaussianCost::Saturating(d, angles, q, zt, {1.0, 2.0});
  ASSERT_TRUE(cost.ok()) << cost.status();
  const int horizon = 15;
  Trajectory tr;
  Vector grad;
  ASSERT_TRUE(PredictTrajectory(prop, *cost, params, mu0, s0, horizon, &tr, &grad).ok());
  EXPECT_TRUE(AllSymmetricPsd(tr));
  EXPECT_GT(tr.covs[horizon].trace(), 2 * s0.trace()) << "the state distribution should move";
  const diff::VectorFunction j = [&](const Vector& th, Vector* out) {
    Trajectory t;
    if (!PredictTrajectory(prop, *cost, th, mu0, s0, horizon, &t, nullptr).ok()) return false;
    *out = Vector::Constant(1, t.total_cost);
    return true;
  };
  diff::CheckOptions check;
  check.relative_step = 1e-6;
  check.relative_tolerance = 1e-5;
  check.absolute_tolerance = 1e-8;
  const diff::CheckResult r = diff::CheckJacobian(j, params, grad.transpose(), check);
  EXPECT_TRUE(r.ok) << r.log;
  // Not a trivial check: the gradient is not negligible. (Dropping the
  // adjoint of Cov(q, p) in StepSeparateBackward fails this test for both
  // control counts; tried when it was written.)
  EXPECT_GT(grad.cwiseAbs().maxCoeff(), 1e-4);
}

INSTANTIATE_TEST_SUITE_P(Controls, SeparateInputsTest,
                         ::testing::Values(SeparateCase{1, false}, SeparateCase{2, false},
                                           SeparateCase{2, true}));

// Per-control length-scales with equal rows are the shared policy: the same
// J (to rounding: unscaled vs scaled gp2), and the gradient rows sum to the
// shared gradient (the shared log l moves every row at once).
TEST(SeparateInputsTest, EqualPerControlLengthscalesAreTheSharedPolicy) {
  std::mt19937_64 rng(61);
  const int d = 4, f = 2, c = 5;
  const GaussianInputGp gp = testing::MakeTestGp(30, 5 + f, d, &rng, 1.5);  // [x0 x2 x3 s c] + u
  PropagationOptions shared;
  shared.angle_index = 1;
  shared.num_basis = c;
  shared.max_controls = Eigen::Vector2d(2.0, 3.0);
  PropagationOptions per = shared;
  per.policy_lengthscale_per_control = true;
  const Propagator a(&gp, shared), b(&gp, per);
  const int ep = a.policy_input_dim();
  Vector pa = testing::RandomVector(a.num_parameters(), 0.5, &rng);
  Vector pb(b.num_parameters());
  pb << pa.head(c * ep), pa.segment(c * ep, ep), pa.segment(c * ep, ep), pa.tail(c * f);
  auto cost = gaussian::GaussianCost::Saturating(d, std::vector<int>{1},
                                       testing::RandomCovariance(d + 2, 0.5, &rng),
                                       Vector::Zero(d + 2), {1.0});
  ASSERT_TRUE(cost.ok());
  const Vector mu0 = Eigen::Vector4d(0.0, 0.2, 0.0, 0.0);
  const Matrix s0 = 0.05 * Matrix::Identity(d, d);
  Trajectory ta, tb;
  Vector ga, gb;
  ASSERT_TRUE(PredictTrajectory(a, *cost, pa, mu0, s0, 10, &ta, &ga).ok());
  ASSERT_TRUE(PredictTrajectory(b, *cost, pb, mu0, s0, 10, &tb, &gb).ok());
  EXPECT_NEAR(ta.total_cost, tb.total_cost, 1e-12 * std::abs(ta.total_cost));
  const double scale = ga.cwiseAbs().maxCoeff();
  EXPECT_TRUE(totalgrad::testing::MatricesNear(ga.head(c * ep), gb.head(c * ep), 1e-10 * scale, 0));
  EXPECT_TRUE(totalgrad::testing::MatricesNear(ga.segment(c * ep, ep),
                                    gb.segment(c * ep, ep) + gb.segment(c * ep + ep, ep),
                                    1e-10 * scale, 0));
  EXPECT_TRUE(totalgrad::testing::MatricesNear(ga.tail(c * f), gb.tail(c * f), 1e-10 * scale, 0));
  // The rows differ (each control's own share), so the split is real.
  EXPECT_GT((gb.segment(c * ep, ep) - gb.segment(c * ep + ep, ep)).cwiseAbs().maxCoeff(),
            1e-3 * scale);
  PropagationOptions one = per;
  one.max_controls.resize(0);
  EXPECT_FALSE(Propagator::Validate(gp, one).ok());
}

// dynamics_inputs equal to the policy's inputs is today's shared path, bit
// for bit; indices out of range or not increasing are refused by name.
TEST(SeparateInputsTest, SharedSetIsTheDefaultPathAndBadSetsAreRefused) {
  std::mt19937_64 rng(60);
  const int d = 4;
  const GaussianInputGp gp = testing::MakeTestGp(30, 6, d, &rng, 1.5);  // [x0 x2 x3 s c] + u
  PropagationOptions base;
  base.angle_index = 1;
  base.num_basis = 4;
  PropagationOptions explicit_sets = base;
  explicit_sets.policy_inputs = {0, 2, 3, 4, 5};
  explicit_sets.dynamics_inputs = {0, 2, 3, 4, 5};
  const Propagator a(&gp, base), b(&gp, explicit_sets);
  Vector params = testing::RandomVector(a.num_parameters(), 0.5, &rng);
  auto cost = gaussian::GaussianCost::Tip(d, 0, 1, 0.5, 0.25);
  ASSERT_TRUE(cost.ok());
  const Vector mu0 = Eigen::Vector4d(0.0, 0.2, 0.0, 0.0);
  const Matrix s0 = 0.01 * Matrix::Identity(d, d);
  Trajectory ta, tb;
  Vector ga, gb;
  ASSERT_TRUE(PredictTrajectory(a, *cost, params, mu0, s0, 10, &ta, &ga).ok());
  ASSERT_TRUE(PredictTrajectory(b, *cost, params, mu0, s0, 10, &tb, &gb).ok());
  EXPECT_EQ(ta.total_cost, tb.total_cost);
  EXPECT_EQ(ga, gb);
  EXPECT_EQ(ta.covs.back(), tb.covs.back());

  for (const std::vector<int>& bad : {std::vector<int>{0, 0, 2, 3, 4}, std::vector<int>{0, 2, 3, 4, 6},
                                      std::vector<int>{3, 2, 0, 4, 5}, std::vector<int>{-1, 2, 3, 4, 5}}) {
    PropagationOptions o = base;
    o.dynamics_inputs = bad;
    const absl::Status st = Propagator::Validate(gp, o);
    ASSERT_FALSE(st.ok());
    EXPECT_NE(st.message().find("dynamics_inputs"), std::string::npos) << st;
    o = base;
    o.policy_inputs = bad;
    const absl::Status sp = Propagator::Validate(gp, o);
    ASSERT_FALSE(sp.ok());
    EXPECT_NE(sp.message().find("policy_inputs"), std::string::npos) << sp;
  }
  PropagationOptions wrong_count = base;
  wrong_count.dynamics_inputs = {0, 2, 4, 5};  // the GP has 5 + 1 inputs
  EXPECT_NE(Propagator::Validate(gp, wrong_count).message().find("inputs; expected 5"),
            std::string::npos);
}

TEST(PropagationTest, PredictionIncludesNoiseAddsTheNoiseVariance) {
  const GaussianInputGp gp = CartPoleGp(60, true, 23);
  PropagationOptions options;
  options.angle_index = 1;
  options.num_basis = 5;
  const Propagator without(&gp, options);
  options.prediction_includes_noise = true;
  const Propagator with(&gp, options);
  auto cost = gaussian::GaussianCost::Tip(4, 0, 1, 0.5, 0.25);
  ASSERT_TRUE(cost.ok());
  const Vector params = InitialPolicy(without, 5, 24);
  Trajectory a, b;
  ASSERT_TRUE(
      PredictTrajectory(without, *cost, params, Vector::Zero(4), 0.01 * Matrix::Identity(4, 4), 5, &a, nullptr).ok());
  ASSERT_TRUE(
      PredictTrajectory(with, *cost, params, Vector::Zero(4), 0.01 * Matrix::Identity(4, 4), 5, &b, nullptr).ok());
  // Step 1: the difference is exactly the noise variances.
  const Vector noise = gp.noise_var;
  EXPECT_TRUE(::totalgrad::testing::MatricesNear(Matrix(b.covs[1] - a.covs[1]).diagonal(), noise,
                                                 1e-12, 0));
}

// ------------------------------------------------------------ degenerate inputs

class DegenerateTest : public ::testing::Test {
 protected:
  DegenerateTest() : gp_(CartPoleGp(50, true, 31)) {
    options_.angle_index = 1;
    options_.num_basis = 6;
    prop_ = std::make_unique<Propagator>(&gp_, options_);
    auto c = gaussian::GaussianCost::Tip(4, 0, 1, 0.5, 0.25);
    cost_ = std::make_unique<gaussian::GaussianCost>(*c);
    params_ = InitialPolicy(*prop_, 6, 32);
  }
  GaussianInputGp gp_;
  PropagationOptions options_;
  std::unique_ptr<Propagator> prop_;
  std::unique_ptr<gaussian::GaussianCost> cost_;
  Vector params_;
};

TEST_F(DegenerateTest, ZeroInputCovarianceIsDeterministicPrediction) {
  Trajectory tr;
  Vector grad;
  ASSERT_TRUE(PredictTrajectory(*prop_, *cost_, params_, Vector::Zero(4), Matrix::Zero(4, 4), 30,
                                &tr, &grad)
                  .ok());
  EXPECT_TRUE(AllSymmetricPsd(tr));
  EXPECT_TRUE(grad.allFinite());
  // One step from a point: the mean is x + GP mean at [x_-a, sin, cos, pi(x)],
  // the covariance the GP's latent variance there.
  StepCache cache;
  Vector m1;
  Matrix s1;
  const Vector x0 = Eigen::Vector4d(0.1, 0.2, -0.3, 0.4);
  ASSERT_TRUE(prop_->Step(params_, x0, Matrix::Zero(4, 4), &m1, &s1, &cache).ok());
  // The only input uncertainty left is the policy's 1e-6 jitter, squashed.
  const double c = cache.policy.sat.c;
  EXPECT_LE(cache.policy.sat.var, c * c * 1e-6 * 1.001 + 1e-15);
  EXPECT_NEAR(cache.g_mean(4), std::cos(0.2), 1e-15);
  EXPECT_NEAR(cache.g_mean(3), std::sin(0.2), 1e-15);
  // The gradient matches finite differences here too.
  const diff::VectorFunction j = [&](const Vector& th, Vector* out) {
    Trajectory t;
    if (!PredictTrajectory(*prop_, *cost_, th, Vector::Zero(4), Matrix::Zero(4, 4), 30, &t,
                           nullptr)
             .ok()) {
      return false;
    }
    *out = Vector::Constant(1, t.total_cost);
    return true;
  };
  diff::CheckOptions check;
  check.relative_tolerance = 1e-5;
  check.absolute_tolerance = 1e-7;
  const diff::CheckResult r = diff::CheckJacobian(j, params_, grad.transpose(), check);
  EXPECT_TRUE(r.ok) << r.log;
}

TEST_F(DegenerateTest, NearlySingularSinCosBlockIsContinuous) {
  // Angle variance 1e-12: the (beta, sin, cos) block has rank ~1.
  Matrix s_tiny = Matrix::Zero(4, 4);
  s_tiny(1, 1) = 1e-12;
  Trajectory tiny, zero;
  Vector g_tiny, g_zero;
  const Vector mu0 = Eigen::Vector4d(0, 0.3, 0, 0);
  ASSERT_TRUE(PredictTrajectory(*prop_, *cost_, params_, mu0, s_tiny, 30, &tiny, &g_tiny).ok());
  ASSERT_TRUE(
      PredictTrajectory(*prop_, *cost_, params_, mu0, Matrix::Zero(4, 4), 30, &zero, &g_zero).ok());
  EXPECT_TRUE(AllSymmetricPsd(tiny));
  EXPECT_NEAR(tiny.total_cost, zero.total_cost, 1e-8);
  EXPECT_TRUE(::totalgrad::testing::MatricesNear(g_tiny, g_zero, 1e-7, 1e-6));
  // The augmented input covariance of step 1 is numerically singular.
  StepCache cache;
  Vector m1;
  Matrix s1;
  ASSERT_TRUE(prop_->Step(params_, mu0, s_tiny, &m1, &s1, &cache).ok());
  const Eigen::VectorXd eig = Eigen::SelfAdjointEigenSolver<Matrix>(cache.p_cov).eigenvalues();
  EXPECT_LT(eig.minCoeff(), 1e-20);
  EXPECT_TRUE(m1.allFinite() && s1.allFinite());
}

TEST_F(DegenerateTest, PolicyFarFromTheDataGivesZeroControl) {
  Vector far = params_;
  const int ep = prop_->policy_input_dim();
  far.head(6 * ep).array() += 1e3;
  Trajectory tr;
  Vector grad;
  ASSERT_TRUE(PredictTrajectory(*prop_, *cost_, far, Vector::Zero(4), 0.01 * Matrix::Identity(4, 4),
                                30, &tr, &grad)
                  .ok());
  EXPECT_TRUE(AllSymmetricPsd(tr));
  EXPECT_TRUE(grad.allFinite());
  StepCache cache;
  Vector m1;
  Matrix s1;
  ASSERT_TRUE(prop_->Step(far, Vector::Zero(4), 0.01 * Matrix::Identity(4, 4), &m1, &s1, &cache).ok());
  EXPECT_LT(std::abs(cache.policy.a_mean), 1e-300);
  EXPECT_NEAR(cache.policy.a_var, 1e-6, 1e-18);  // only the jitter
}

TEST_F(DegenerateTest, StateFarFromTheGpDataRevertsToThePrior) {
  const Vector far = Eigen::Vector4d(1e4, 0.0, -1e4, 1e4);
  Vector m1;
  Matrix s1;
  ASSERT_TRUE(prop_->Step(params_, far, 0.01 * Matrix::Identity(4, 4), &m1, &s1, nullptr).ok());
  EXPECT_TRUE(::totalgrad::testing::MatricesNear(m1, far, 1e-9, 0));
  // Prior variance sf^2 added on the diagonal.
  for (int a = 0; a < 4; ++a) EXPECT_NEAR(s1(a, a), 0.01 + gp_.signal_var(a), 1e-9);
}

TEST_F(DegenerateTest, NonPsdCovarianceIsAClearError) {
  Matrix bad = 0.01 * Matrix::Identity(4, 4);
  bad(2, 2) = -5.0;
  Trajectory tr;
  const absl::Status st =
      PredictTrajectory(*prop_, *cost_, params_, Vector::Zero(4), bad, 30, &tr, nullptr);
  EXPECT_EQ(st.code(), absl::StatusCode::kFailedPrecondition) << st;
  EXPECT_NE(st.message().find("step 1"), std::string::npos) << st;
  EXPECT_NE(st.message().find("positive"), std::string::npos) << st;
}

TEST_F(DegenerateTest, NonFiniteInputIsAClearError) {
  Vector mu0 = Vector::Zero(4);
  mu0(2) = std::nan("");
  Trajectory tr;
  const absl::Status st = PredictTrajectory(*prop_, *cost_, params_, mu0,
                                            0.01 * Matrix::Identity(4, 4), 30, &tr, nullptr);
  EXPECT_EQ(st.code(), absl::StatusCode::kInvalidArgument) << st;
}

TEST(GpFromDataTest, FailedFactorisationIsAClearError) {
  RowMatrix x = RowMatrix::Zero(3, 2);  // duplicate inputs
  RowMatrix y(3, 1);
  y << 1, 2, 3;
  RowMatrix log_hyp(1, 4);
  log_hyp << 0, 0, 0, -400;  // sn = e^-400: K singular
  auto gp = GaussianInputGpFromData(x, y, log_hyp);
  ASSERT_FALSE(gp.ok());
  EXPECT_EQ(gp.status().code(), absl::StatusCode::kFailedPrecondition);
  EXPECT_NE(gp.status().message().find("output 0"), std::string::npos) << gp.status();
}

}  // namespace propagation_test
}  // namespace totalgrad::pilco
