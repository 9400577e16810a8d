#include "core/policy/rbf_policy.h"

#include <cmath>

#include <gtest/gtest.h>

#include "core/diff/gradient_checker.h"

namespace totalgrad::policy {
namespace {

RbfPolicy MakePolicy(uint64_t seed) {
  RbfPolicy policy(7, 4, 10.0);
  Rng rng(seed, Stream::kPolicyInit);
  Vector mean(4);
  mean << 0.1, 1.0, -0.2, 0.5;
  policy.Initialize(mean, Vector::Constant(4, 1.0), 0.8, &rng);
  // Spread the length-scales so each dimension has its own scale.
  Vector p = policy.parameters();
  p.segment(7 * 4, 4) << std::log(0.7), std::log(1.3), std::log(2.0), std::log(0.9);
  // Bigger weights so the saturation's curvature matters.
  p.tail(7) *= 4.0;
  policy.set_parameters(p);
  return policy;
}

RowMatrix States(int p, uint64_t seed) {
  Rng rng(seed, Stream::kStudy);
  RowMatrix x(p, 4);
  rng.FillNormal(&x);
  return x;
}

TEST(Saturate, KnownValues) {
  // pipps-spec.md 1.8 test vectors (u_max = 1).
  EXPECT_NEAR(Saturate(0.3, 1.0), 0.4303760962, 1e-9);
  EXPECT_NEAR(Saturate(1.0, 1.0), 0.9642948589, 1e-9);
  EXPECT_NEAR(Saturate(M_PI / 2, 1.0), 1.0, 1e-15);
  EXPECT_NEAR(Saturate(2.0, 1.0), 0.9880326679, 1e-9);
  EXPECT_NEAR(Saturate(M_PI / 2, 10.0), 10.0, 1e-13);
}

TEST(Saturate, DerivativeMatchesFiniteDifference) {
  for (double a : {-2.0, -0.3, 0.0, 0.4, 1.2, 3.0}) {
    const double h = 1e-6;
    EXPECT_NEAR(DaSaturate(a, 10.0), (Saturate(a + h, 10.0) - Saturate(a - h, 10.0)) / (2 * h), 1e-7);
  }
}

TEST(RbfPolicy, ParameterCountMatchesPaper) {
  RbfPolicy policy(50, 4, 10.0);
  EXPECT_EQ(policy.num_parameters(), 254);
}

TEST(RbfPolicy, EvaluateMatchesDefinition) {
  const RbfPolicy policy = MakePolicy(3);
  const RowMatrix x = States(5, 4);
  Vector forces;
  policy.Evaluate(x, &forces, nullptr);
  for (int i = 0; i < 5; ++i) {
    double a = 0;
    for (int k = 0; k < 7; ++k) {
      double q = 0;
      for (int m = 0; m < 4; ++m) {
        const double l = std::exp(policy.log_lengthscales()(m));
        const double d = (x(i, m) - policy.centres()(k, m)) / l;
        q += d * d;
      }
      a += policy.weights()(k) * std::exp(-0.5 * q);
    }
    EXPECT_NEAR(forces(i), Saturate(a, 10.0), 1e-12);
  }
}

// A policy on S state dimensions with spread length-scales and weights large
// enough for the saturation's curvature to matter.
RbfPolicy MakePolicyOfDimension(int s_dim, uint64_t seed) {
  RbfPolicy policy(7, s_dim, 10.0);
  Rng rng(seed, Stream::kPolicyInit);
  policy.Initialize(Vector::LinSpaced(s_dim, -0.3, 0.8), Vector::Constant(s_dim, 1.0), 0.8, &rng);
  Vector p = policy.parameters();
  p.segment(7 * s_dim, s_dim) = Vector::LinSpaced(s_dim, std::log(0.7), std::log(2.0));
  p.tail(7) *= 4.0;
  policy.set_parameters(p);
  return policy;
}

// d force_i / d theta against central differences, for the cart-pole's S = 4
// (vectorised path) and other dimensions (generic path: 2, 5 = sin/cos
// features, 6).
class RbfPolicyDims : public ::testing::TestWithParam<int> {};

TEST_P(RbfPolicyDims, ParameterGradientMatchesFiniteDifferences) {
  const int s_dim = GetParam();
  RbfPolicy policy = MakePolicyOfDimension(s_dim, 11);
  Rng rng(12, Stream::kStudy);
  RowMatrix x(5, s_dim);
  rng.FillNormal(&x);
  RbfPolicy::Cache cache;
  Vector forces;
  policy.Evaluate(x, &forces, &cache);
  RowMatrix per_particle = RowMatrix::Zero(5, policy.num_parameters());
  policy.Backward(cache, Vector::Ones(5), nullptr, &per_particle, nullptr);
  const Matrix analytic = per_particle;
  const diff::VectorFunction f = [&](const Vector& theta, Vector* out) {
    RbfPolicy copy = policy;
    copy.set_parameters(theta);
    copy.Evaluate(x, out, nullptr);
    return true;
  };
  const diff::CheckResult r = diff::CheckJacobian(f, policy.parameters(), analytic);
  EXPECT_TRUE(r.ok) << r.log;
}

INSTANTIATE_TEST_SUITE_P(StateDimensions, RbfPolicyDims, ::testing::Values(2, 4, 5, 6));

// d force_i / d theta and d force_i / d x_i against central differences.
TEST(RbfPolicy, ParameterGradientMatchesFiniteDifferences) {
  RbfPolicy policy = MakePolicy(5);
  const RowMatrix x = States(6, 6);
  const int n = policy.num_parameters();
  RbfPolicy::Cache cache;
  Vector forces;
  policy.Evaluate(x, &forces, &cache);
  // Analytic Jacobian: row i = d force_i / d theta, via force_bar = e_i.
  Matrix analytic(6, n);
  RowMatrix per_particle = RowMatrix::Zero(6, n);
  policy.Backward(cache, Vector::Ones(6), nullptr, &per_particle, nullptr);
  analytic = per_particle;
  const diff::VectorFunction f = [&](const Vector& theta, Vector* out) {
    RbfPolicy copy = policy;
    copy.set_parameters(theta);
    copy.Evaluate(x, out, nullptr);
    return true;
  };
  const diff::CheckResult r = diff::CheckJacobian(f, policy.parameters(), analytic);
  EXPECT_TRUE(r.ok) << r.log;

  // The summed gradient equals the column sums, with force_bar weights.
  Vector weights(6);
  weights << 0.3, -1.0, 2.0, 0.5, -0.7, 1.1;
  Vector summed = Vector::Zero(n);
  RowMatrix weighted = RowMatrix::Zero(6, n);
  policy.Backward(cache, weights, nullptr, &weighted, &summed);
  const Vector expected = analytic.transpose() * weights;
  EXPECT_LT((summed - expected).cwiseAbs().maxCoeff(), 1e-10);
  EXPECT_LT((weighted.colwise().sum().transpose() - expected).cwiseAbs().maxCoeff(), 1e-10);
}

TEST(RbfPolicy, StateGradientMatchesFiniteDifferences) {
  const RbfPolicy policy = MakePolicy(7);
  const RowMatrix x = States(3, 8);
  RbfPolicy::Cache cache;
  Vector forces;
  policy.Evaluate(x, &forces, &cache);
  RowMatrix state_bar;
  policy.Backward(cache, Vector::Ones(3), &state_bar, nullptr, nullptr);
  for (int i = 0; i < 3; ++i) {
    const diff::VectorFunction f = [&](const Vector& xi, Vector* out) {
      RowMatrix one = xi.transpose();
      policy.Evaluate(one, out, nullptr);
      return true;
    };
    const Matrix analytic = state_bar.row(i);
    const diff::CheckResult r = diff::CheckJacobian(f, x.row(i).transpose(), analytic);
    EXPECT_TRUE(r.ok) << "particle " << i << ": " << r.log;
  }
}

TEST(RbfPolicy, WrongGradientIsCaught) {
  RbfPolicy policy = MakePolicy(9);
  const RowMatrix x = States(2, 10);
  RbfPolicy::Cache cache;
  Vector forces;
  policy.Evaluate(x, &forces, &cache);
  RowMatrix per_particle = RowMatrix::Zero(2, policy.num_parameters());
  policy.Backward(cache, Vector::Ones(2), nullptr, &per_particle, nullptr);
  Matrix wrong = per_particle;
  wrong(0, 7 * 4 + 1) *= 1.01;  // a log-length-scale entry off by 1%
  const diff::VectorFunction f = [&](const Vector& theta, Vector* out) {
    RbfPolicy copy = policy;
    copy.set_parameters(theta);
    copy.Evaluate(x, out, nullptr);
    return true;
  };
  EXPECT_FALSE(diff::CheckJacobian(f, policy.parameters(), wrong).ok);
}

}  // namespace
}  // namespace totalgrad::policy
