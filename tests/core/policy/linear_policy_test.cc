// The particle form of PILCO's linear policy (core/policy/linear_policy.h):
// hand-computed controls, every adjoint against central differences, a
// wrong adjoint caught, and the same parameter vector as the moment-matched
// form (pilco::Propagator with PolicyClass::kLinear): its sample mean and
// covariance are the moment-matched ones.
#include "core/policy/linear_policy.h"

#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "core/diff/gradient_checker.h"
#include "core/pilco/linear_policy.h"

namespace totalgrad::policy {
namespace linear_policy_test {

// S = 3 inputs, F = 2 controls with bounds [10, 50] (the unicycle's).
LinearPolicy MakePolicy(unsigned seed) {
  LinearPolicy policy(3, Eigen::Vector2d(10.0, 50.0));
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> normal;
  Vector p(policy.num_parameters());
  for (Eigen::Index k = 0; k < p.size(); ++k) p(k) = 0.6 * normal(rng);
  policy.set_parameters(p);
  return policy;
}

RowMatrix States(int count, unsigned seed) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> normal;
  RowMatrix x(count, 3);
  for (int i = 0; i < count; ++i) {
    for (int m = 0; m < 3; ++m) x(i, m) = normal(rng);
  }
  return x;
}

TEST(LinearPolicy, LayoutAndHandComputedControls) {
  LinearPolicy policy(2, Eigen::Vector2d(10.0, 50.0));
  ASSERT_EQ(policy.num_parameters(), 6);
  // W = [[0.1, 0.3], [0.2, -0.4]] column-major, b = [0.05, -0.1].
  Vector p(6);
  p << 0.1, 0.2, 0.3, -0.4, 0.05, -0.1;
  policy.set_parameters(p);
  EXPECT_EQ(policy.gain()(0, 1), 0.3);
  EXPECT_EQ(policy.gain()(1, 0), 0.2);
  EXPECT_EQ(policy.bias()(1), -0.1);
  RowMatrix x(1, 2);
  x << 1.0, 2.0;
  Vector u;
  policy.Evaluate(x, &u, nullptr);
  ASSERT_EQ(u.size(), 2);
  const double a0 = 0.1 * 1.0 + 0.3 * 2.0 + 0.05;   // 0.75
  const double a1 = 0.2 * 1.0 - 0.4 * 2.0 - 0.1;    // -0.7
  EXPECT_NEAR(u(0), 10.0 * (9 * std::sin(a0) + std::sin(3 * a0)) / 8, 1e-14);
  EXPECT_NEAR(u(1), 50.0 * (9 * std::sin(a1) + std::sin(3 * a1)) / 8, 1e-13);
}

TEST(LinearPolicy, AdjointsMatchCentralDifferences) {
  const LinearPolicy policy = MakePolicy(1);
  const int p_count = 5, f = 2, s = 3;
  const RowMatrix x = States(p_count, 2);
  std::mt19937_64 rng(3);
  std::normal_distribution<double> normal;
  Vector force_bar(p_count * f);
  for (Eigen::Index k = 0; k < force_bar.size(); ++k) force_bar(k) = normal(rng);
  RbfPolicy::Cache cache;
  Vector u;
  policy.Evaluate(x, &u, &cache);
  RowMatrix state_bar;
  RowMatrix per_particle = RowMatrix::Zero(p_count, policy.num_parameters());
  Vector param_bar = Vector::Zero(policy.num_parameters());
  policy.Backward(cache, force_bar, &state_bar, &per_particle, &param_bar);
  // L(theta) = force_bar . u(x; theta).
  const diff::VectorFunction by_params = [&](const Vector& theta, Vector* out) {
    LinearPolicy moved = policy;
    moved.set_parameters(theta);
    Vector v;
    moved.Evaluate(x, &v, nullptr);
    *out = Vector::Constant(1, force_bar.dot(v));
    return true;
  };
  diff::CheckOptions check;
  check.relative_tolerance = 1e-6;
  check.absolute_tolerance = 1e-8;
  diff::CheckResult r =
      diff::CheckJacobian(by_params, policy.parameters(), param_bar.transpose(), check);
  EXPECT_TRUE(r.ok) << r.log;
  EXPECT_LT((per_particle.colwise().sum().transpose() - param_bar).cwiseAbs().maxCoeff(), 1e-12);
  // Row i of the state adjoint: particle i's own states only.
  for (int i = 0; i < p_count; ++i) {
    const diff::VectorFunction by_state = [&](const Vector& xi, Vector* out) {
      RowMatrix moved = x;
      moved.row(i) = xi.transpose();
      Vector v;
      policy.Evaluate(moved, &v, nullptr);
      *out = Vector::Constant(1, force_bar.dot(v));
      return true;
    };
    r = diff::CheckJacobian(by_state, x.row(i).transpose(), state_bar.row(i), check);
    EXPECT_TRUE(r.ok) << "particle " << i << ": " << r.log;
  }
  EXPECT_GT(param_bar.cwiseAbs().maxCoeff(), 1e-3);
  EXPECT_EQ(state_bar.cols(), s);
}

TEST(LinearPolicy, AWrongAdjointIsCaught) {
  // The bias's adjoint without the saturation's slope: the check must fail.
  const LinearPolicy policy = MakePolicy(4);
  const RowMatrix x = States(3, 5);
  const Vector force_bar = Vector::Ones(6);
  RbfPolicy::Cache cache;
  Vector u;
  policy.Evaluate(x, &u, &cache);
  Vector param_bar = Vector::Zero(policy.num_parameters());
  policy.Backward(cache, force_bar, nullptr, nullptr, &param_bar);
  param_bar.tail(2) = Eigen::Vector2d(3.0, 3.0);  // sum of force_bar per control
  const diff::VectorFunction j = [&](const Vector& theta, Vector* out) {
    LinearPolicy moved = policy;
    moved.set_parameters(theta);
    Vector v;
    moved.Evaluate(x, &v, nullptr);
    *out = Vector::Constant(1, force_bar.dot(v));
    return true;
  };
  EXPECT_FALSE(diff::CheckJacobian(j, policy.parameters(), param_bar.transpose()).ok);
}

// The same parameter vector read as pilco::LinearPolicy (W column-major,
// b): the sample moments of the particle form over 4 10^5 states from N(m,
// S) are LinearPolicyForward's exact ones (within 5 standard errors).
TEST(LinearPolicy, SampleMomentsAreTheMomentMatchedOnes) {
  const LinearPolicy policy = MakePolicy(6);
  pilco::LinearPolicy mm;
  mm.w = policy.gain();
  mm.b = policy.bias();
  mm.max_u = policy.max_control();
  const Vector m = Eigen::Vector3d(0.2, -0.1, 0.4);
  Matrix root(3, 3);
  root << 0.5, 0.0, 0.0, 0.2, 0.4, 0.0, -0.1, 0.3, 0.6;
  const Matrix s = root * root.transpose();
  pilco::LinearPolicyMoments exact;
  pilco::LinearPolicyForward(mm, m, s, &exact);
  const int n = 400000;
  RowMatrix e = States(n, 7);
  const RowMatrix x = (e * root.transpose()).rowwise() + m.transpose();
  Vector u;
  policy.Evaluate(x, &u, nullptr);
  const Eigen::Map<const RowMatrix> uu(u.data(), n, 2);
  const Vector mean = uu.colwise().mean().transpose();
  const RowMatrix centred = uu.rowwise() - mean.transpose();
  const Matrix cov = centred.transpose() * centred / (n - 1);
  for (int j = 0; j < 2; ++j) {
    const double se = std::sqrt(cov(j, j) / n);
    EXPECT_NEAR(mean(j), exact.mean(j), 5 * se) << "control " << j;
    // Var of a sample variance ~ 2 sigma^4 / n for a near-Gaussian u.
    EXPECT_NEAR(cov(j, j), exact.cov(j, j), 5 * std::sqrt(2.0 / n) * exact.cov(j, j) + 1e-12)
        << "control " << j;
  }
  EXPECT_GT(exact.cov(1, 1), 1.0) << "the wheel torque should be uncertain";
}

}  // namespace linear_policy_test
}  // namespace totalgrad::policy
