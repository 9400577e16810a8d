#include "core/policy/rbf_policy.h"

#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "core/diff/gradient_checker.h"

namespace totalgrad::policy {
namespace rbf_policy_test {

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

// ---------------------------------------------------------------- F outputs
// (the double pendulum's two torques): u_ij = Saturate(a_ij, max_j),
// a_ij = sum_k w_kj phi_ik, weights row-major C x F after the length-scales.

// A policy on S dims with F outputs, each output its own bound, spread
// length-scales and weights large enough for the saturation's curvature.
RbfPolicy MakeMultiOutputPolicy(int s_dim, int f_count, uint64_t seed) {
  RbfPolicy policy(7, s_dim, Vector::LinSpaced(f_count, 2.0, 3.5));
  Rng rng(seed, Stream::kPolicyInit);
  policy.Initialize(Vector::LinSpaced(s_dim, -0.3, 0.8), Vector::Constant(s_dim, 1.0), 0.8, &rng);
  Vector p = policy.parameters();
  p.segment(7 * s_dim, s_dim) = Vector::LinSpaced(s_dim, std::log(0.7), std::log(2.0));
  p.tail(7 * f_count) *= 4.0;
  policy.set_parameters(p);
  return policy;
}

TEST(RbfPolicyOutputs, ParameterCountAndLayout) {
  const RbfPolicy policy(50, 6, Vector::Constant(2, 2.0));
  EXPECT_EQ(policy.control_dim(), 2);
  EXPECT_EQ(policy.num_parameters(), 50 * 6 + 6 + 50 * 2);
  EXPECT_EQ(policy.weights().size(), 100);
}

TEST(RbfPolicyOutputs, EvaluateMatchesDefinitionWithEachOutputsBound) {
  const int s_dim = 4, f_count = 2, p = 5;
  const RbfPolicy policy = MakeMultiOutputPolicy(s_dim, f_count, 21);
  RowMatrix x(p, s_dim);
  Rng rng(22, Stream::kStudy);
  rng.FillNormal(&x);
  Vector u;
  policy.Evaluate(x, &u, nullptr);
  ASSERT_EQ(u.size(), p * f_count);
  const Eigen::Map<const RowMatrix> w(policy.weights().data(), 7, f_count);
  double largest_pre = 0;
  for (int i = 0; i < p; ++i) {
    for (int j = 0; j < f_count; ++j) {
      double a = 0;
      for (int k = 0; k < 7; ++k) {
        double q = 0;
        for (int m = 0; m < s_dim; ++m) {
          const double d = (x(i, m) - policy.centres()(k, m)) / std::exp(policy.log_lengthscales()(m));
          q += d * d;
        }
        a += w(k, j) * std::exp(-0.5 * q);
      }
      largest_pre = std::max(largest_pre, std::abs(a));
      // Particle-major: particle i's controls at i F .. i F + F - 1.
      EXPECT_NEAR(u(i * f_count + j), Saturate(a, policy.max_control()(j)), 1e-12) << i << " " << j;
    }
  }
  EXPECT_GT(largest_pre, 0.5) << "the saturation's curvature should matter";
  // Equal weight columns: the outputs differ by their bounds alone, so a bound
  // applied to the wrong output is seen.
  RbfPolicy same = policy;
  Vector theta = policy.parameters();
  Eigen::Map<RowMatrix> wt(theta.data() + 7 * s_dim + s_dim, 7, f_count);
  wt.col(1) = wt.col(0);
  same.set_parameters(theta);
  same.Evaluate(x, &u, nullptr);
  for (int i = 0; i < p; ++i)
    EXPECT_NEAR(u(i * f_count + 1) / u(i * f_count), 3.5 / 2.0, 1e-13);
}

// One bound as a 1-vector is the one-output policy: the same parameters, the
// same draws, the same bits.
TEST(RbfPolicyOutputs, OneOutputVectorIsTheScalarPolicyBitForBit) {
  RbfPolicy scalar(7, 4, 10.0), vec(7, 4, Vector::Constant(1, 10.0));
  Rng r1(5, Stream::kPolicyInit), r2(5, Stream::kPolicyInit);
  const Vector mean = Vector::LinSpaced(4, -0.3, 0.8);
  scalar.Initialize(mean, Vector::Constant(4, 1.0), 0.8, &r1);
  vec.Initialize(mean, Vector::Constant(4, 1.0), 0.8, &r2);
  ASSERT_EQ(scalar.parameters(), vec.parameters());
  const RowMatrix x = States(6, 3);
  RbfPolicy::Cache c1, c2;
  Vector u1, u2;
  scalar.Evaluate(x, &u1, &c1);
  vec.Evaluate(x, &u2, &c2);
  EXPECT_EQ(u1, u2);
  Vector fb(6);
  fb << 0.3, -1.0, 2.0, 0.5, -0.7, 1.1;
  RowMatrix s1, s2, pp1 = RowMatrix::Zero(6, scalar.num_parameters()), pp2 = pp1;
  scalar.Backward(c1, fb, &s1, &pp1, nullptr);
  vec.Backward(c2, fb, &s2, &pp2, nullptr);
  EXPECT_EQ(s1, s2);
  EXPECT_EQ(pp1, pp2);
}

// du_ij/dtheta and du_ij/dx_i against central differences, for S = 4 (the
// vectorised parameter adjoint) and S = 6 (the double pendulum's features,
// generic path), F = 2 and 3; and the summed adjoint of a general force_bar.
struct OutputsCase {
  int s_dim;
  int f_count;
};
class RbfPolicyOutputDims : public ::testing::TestWithParam<OutputsCase> {};

TEST_P(RbfPolicyOutputDims, AdjointsMatchFiniteDifferences) {
  const int s_dim = GetParam().s_dim, f_count = GetParam().f_count, p = 4;
  const RbfPolicy policy = MakeMultiOutputPolicy(s_dim, f_count, 31);
  const int n = policy.num_parameters();
  RowMatrix x(p, s_dim);
  Rng rng(32, Stream::kStudy);
  rng.FillNormal(&x);
  RbfPolicy::Cache cache;
  Vector u;
  policy.Evaluate(x, &u, &cache);
  // Row i F + j of the Jacobian: the adjoint of force_bar = 1 on control j of
  // every particle lands in particle i's row.
  Matrix analytic(p * f_count, n);
  std::vector<RowMatrix> state_rows(f_count);
  for (int j = 0; j < f_count; ++j) {
    Vector fb = Vector::Zero(p * f_count);
    for (int i = 0; i < p; ++i) fb(i * f_count + j) = 1.0;
    RowMatrix rows = RowMatrix::Zero(p, n);
    policy.Backward(cache, fb, &state_rows[j], &rows, nullptr);
    for (int i = 0; i < p; ++i) analytic.row(i * f_count + j) = rows.row(i);
  }
  const diff::VectorFunction f = [&](const Vector& theta, Vector* out) {
    RbfPolicy copy = policy;
    copy.set_parameters(theta);
    copy.Evaluate(x, out, nullptr);
    return true;
  };
  const diff::CheckResult r = diff::CheckJacobian(f, policy.parameters(), analytic);
  EXPECT_TRUE(r.ok) << r.log;
  // Layout: control j depends on its own weights w_kj (entry C S + S + k F
  // + j) and not at all on another control's.
  for (int j = 0; j < f_count; ++j) {
    double own = 0;
    for (int i = 0; i < p; ++i) {
      for (int k = 0; k < 7; ++k) {
        for (int l = 0; l < f_count; ++l) {
          const double d = analytic(i * f_count + j, 7 * s_dim + s_dim + k * f_count + l);
          if (l == j) own = std::max(own, std::abs(d));
          else EXPECT_EQ(d, 0.0) << "control " << j << " on weight (" << k << ", " << l << ")";
        }
      }
    }
    EXPECT_GT(own, 1e-3) << "control " << j;
  }

  for (int i = 0; i < p; ++i) {
    const diff::VectorFunction g = [&](const Vector& xi, Vector* out) {
      policy.Evaluate(xi.transpose(), out, nullptr);
      return true;
    };
    Matrix state_jacobian(f_count, s_dim);
    for (int j = 0; j < f_count; ++j) state_jacobian.row(j) = state_rows[j].row(i);
    const diff::CheckResult rs = diff::CheckJacobian(g, x.row(i).transpose(), state_jacobian);
    EXPECT_TRUE(rs.ok) << "particle " << i << ": " << rs.log;
  }

  // A general force_bar: param_bar and the per-particle rows are the
  // Jacobian's transpose times it, state_bar the sum of the per-control rows.
  Vector fb(p * f_count);
  Rng frng(33, Stream::kStudy);
  for (int k = 0; k < fb.size(); ++k) fb(k) = frng.Normal();
  Vector summed = Vector::Zero(n);
  RowMatrix weighted = RowMatrix::Zero(p, n), state_bar;
  policy.Backward(cache, fb, &state_bar, &weighted, &summed);
  const Vector expected = analytic.transpose() * fb;
  EXPECT_LT((summed - expected).cwiseAbs().maxCoeff(), 1e-10);
  EXPECT_LT((weighted.colwise().sum().transpose() - expected).cwiseAbs().maxCoeff(), 1e-10);
  for (int i = 0; i < p; ++i) {
    Vector row = Vector::Zero(s_dim);
    for (int j = 0; j < f_count; ++j) row += fb(i * f_count + j) * state_rows[j].row(i).transpose();
    EXPECT_LT((state_bar.row(i).transpose() - row).cwiseAbs().maxCoeff(), 1e-10);
  }
}

INSTANTIATE_TEST_SUITE_P(Outputs, RbfPolicyOutputDims,
                         ::testing::Values(OutputsCase{4, 2}, OutputsCase{6, 2}, OutputsCase{4, 3}),
                         [](const auto& info) {
                           return "S" + std::to_string(info.param.s_dim) + "F" +
                                  std::to_string(info.param.f_count);
                         });

TEST(RbfPolicyOutputs, WrongSecondOutputGradientIsCaught) {
  const RbfPolicy policy = MakeMultiOutputPolicy(4, 2, 41);
  RowMatrix x(3, 4);
  Rng rng(42, Stream::kStudy);
  rng.FillNormal(&x);
  RbfPolicy::Cache cache;
  Vector u;
  policy.Evaluate(x, &u, &cache);
  const int n = policy.num_parameters();
  Matrix analytic(6, n);
  for (int j = 0; j < 2; ++j) {
    Vector fb = Vector::Zero(6);
    for (int i = 0; i < 3; ++i) fb(i * 2 + j) = 1.0;
    RowMatrix rows = RowMatrix::Zero(3, n);
    policy.Backward(cache, fb, nullptr, &rows, nullptr);
    for (int i = 0; i < 3; ++i) analytic.row(i * 2 + j) = rows.row(i);
  }
  const diff::VectorFunction f = [&](const Vector& theta, Vector* out) {
    RbfPolicy copy = policy;
    copy.set_parameters(theta);
    copy.Evaluate(x, out, nullptr);
    return true;
  };
  ASSERT_TRUE(diff::CheckJacobian(f, policy.parameters(), analytic).ok);
  // The second output's derivative along basis 2's second-output weight,
  // off by 1%: caught.
  Matrix wrong = analytic;
  wrong(1, 7 * 4 + 4 + 2 * 2 + 1) *= 1.01;
  EXPECT_FALSE(diff::CheckJacobian(f, policy.parameters(), wrong).ok);
}

}  // namespace rbf_policy_test
}  // namespace totalgrad::policy
