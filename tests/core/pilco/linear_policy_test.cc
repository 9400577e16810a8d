// The linear policy with saturation under a Gaussian state
// (core/pilco/linear_policy.h): its moments against Monte Carlo, every
// adjoint against central differences, and one control against the
// one-control saturation GSat.
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "core/pilco/linear_policy.h"
#include "core/pilco/saturation.h"

namespace totalgrad::pilco {
namespace linear_policy_test {

// The unicycle's shape: D = 10 inputs, F = 2 controls (maxU [10, 50]).
struct Case {
  LinearPolicy policy;
  Vector m;
  Matrix s;
};

Case MakeCase(unsigned seed, int d = 10) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> normal;
  Case c;
  c.policy.w = Matrix(2, d);
  for (int i = 0; i < 2; ++i) {
    for (int j = 0; j < d; ++j) c.policy.w(i, j) = 0.5 * normal(rng);
  }
  c.policy.b = Eigen::Vector2d(0.3 * normal(rng), 0.3 * normal(rng));
  c.policy.max_u = Eigen::Vector2d(10.0, 50.0);
  c.m = Vector(d);
  for (int i = 0; i < d; ++i) c.m(i) = 0.5 * normal(rng);
  Matrix root(d, d);
  for (int i = 0; i < d; ++i) {
    for (int j = 0; j < d; ++j) root(i, j) = 0.4 * normal(rng) / std::sqrt(double(d));
  }
  c.s = root * root.transpose();
  return c;
}

TEST(LinearPolicyTest, MomentsMatchMonteCarlo) {
  const Case c = MakeCase(3);
  LinearPolicyMoments moments;
  LinearPolicyForward(c.policy, c.m, c.s, &moments);
  const int d = 10, samples = 1000000;
  const Matrix root = c.s.llt().matrixL();
  std::mt19937_64 rng(5);
  std::normal_distribution<double> normal;
  Eigen::Vector2d u_sum = Eigen::Vector2d::Zero();
  Eigen::Matrix2d u_outer = Eigen::Matrix2d::Zero();
  Matrix cross_sum = Matrix::Zero(d, 2);
  Vector e(d);
  for (int k = 0; k < samples; ++k) {
    for (int i = 0; i < d; ++i) e(i) = normal(rng);
    const Vector x = c.m + root * e;
    const Vector a = c.policy.w * x + c.policy.b;
    Eigen::Vector2d u;
    for (int j = 0; j < 2; ++j) {
      u(j) = c.policy.max_u(j) * (9 * std::sin(a(j)) + std::sin(3 * a(j))) / 8;
    }
    u_sum += u;
    u_outer += (u - moments.mean) * (u - moments.mean).transpose();
    cross_sum += (x - c.m) * (u - moments.mean).transpose();
  }
  const Eigen::Vector2d u_mean = u_sum / samples;
  for (int j = 0; j < 2; ++j) {
    EXPECT_NEAR(u_mean(j), moments.mean(j), 5 * std::sqrt(moments.cov(j, j) / samples));
    for (int k = 0; k < 2; ++k) {
      const double se =
          std::sqrt((moments.cov(j, j) * moments.cov(k, k) + std::pow(moments.cov(j, k), 2)) /
                    samples);
      EXPECT_NEAR(u_outer(j, k) / samples, moments.cov(j, k), 5 * se) << j << "," << k;
    }
    for (int i = 0; i < d; ++i) {
      const double se = std::sqrt(c.s(i, i) * moments.cov(j, j) / samples);
      EXPECT_NEAR(cross_sum(i, j) / samples, moments.cross(i, j), 5 * se) << i << "," << j;
    }
  }
}

TEST(LinearPolicyTest, OneControlIsGSatOfTheLinearMap) {
  Case c = MakeCase(7, 4);
  c.policy.w = c.policy.w.topRows(1).eval();
  c.policy.b = c.policy.b.head(1).eval();
  c.policy.max_u = Vector::Constant(1, 3.5);
  LinearPolicyMoments moments;
  LinearPolicyForward(c.policy, c.m, c.s, &moments);
  const double a_mean = (c.policy.w * c.m)(0) + c.policy.b(0);
  const double a_var = (c.policy.w * c.s * c.policy.w.transpose())(0, 0);
  const SatMoments sat = GSat(a_mean, a_var, 3.5);
  EXPECT_NEAR(moments.mean(0), sat.mean, 1e-12);
  EXPECT_NEAR(moments.cov(0, 0), sat.var, 1e-12);
  const Vector cross = c.s * c.policy.w.transpose() * sat.c;
  EXPECT_LT((moments.cross.col(0) - cross).cwiseAbs().maxCoeff(), 1e-12);
}

TEST(LinearPolicyTest, AdjointsMatchCentralDifferences) {
  const Case c = MakeCase(11);
  const int d = 10;
  // A random linear functional of every output.
  std::mt19937_64 rng(13);
  std::normal_distribution<double> normal;
  const Vector mean_bar = Eigen::Vector2d(normal(rng), normal(rng));
  Matrix cov_bar(2, 2), cross_bar(d, 2), u_cross_bar(d, 2);
  for (int i = 0; i < 2; ++i) {
    for (int j = 0; j < 2; ++j) cov_bar(i, j) = normal(rng);
  }
  for (int i = 0; i < d; ++i) {
    for (int j = 0; j < 2; ++j) {
      cross_bar(i, j) = normal(rng);
      u_cross_bar(i, j) = normal(rng);
    }
  }
  // u_cross is S^-1 Cov(x, u), as the propagation carries it.
  LinearPolicyMoments at_case;
  LinearPolicyForward(c.policy, c.m, c.s, &at_case);
  EXPECT_LT((c.s * at_case.u_cross - at_case.cross).norm(), 1e-12 * at_case.cross.norm());
  auto objective = [&](const LinearPolicy& p, const Vector& m, const Matrix& s) {
    LinearPolicyMoments out;
    LinearPolicyForward(p, m, s, &out);
    return mean_bar.dot(out.mean) + cov_bar.cwiseProduct(out.cov).sum() +
           cross_bar.cwiseProduct(out.cross).sum() + u_cross_bar.cwiseProduct(out.u_cross).sum();
  };
  Vector m_bar = Vector::Zero(d), b_bar = Vector::Zero(2);
  Matrix s_bar = Matrix::Zero(d, d), w_bar = Matrix::Zero(2, d);
  LinearPolicyBackward(c.policy, c.m, c.s, mean_bar, cov_bar, cross_bar, &m_bar, &s_bar, &w_bar,
                       &b_bar, &u_cross_bar);
  const double h = 1e-6, tol = 1e-6;
  for (int i = 0; i < d; ++i) {
    Vector up = c.m, down = c.m;
    up(i) += h;
    down(i) -= h;
    EXPECT_NEAR(m_bar(i), (objective(c.policy, up, c.s) - objective(c.policy, down, c.s)) / (2 * h),
                tol) << "m " << i;
    for (int j = 0; j <= i; ++j) {  // S stays symmetric: perturb (i, j) and (j, i) together
      Matrix su = c.s, sd = c.s;
      su(i, j) += h;
      sd(i, j) -= h;
      if (i != j) {
        su(j, i) += h;
        sd(j, i) -= h;
      }
      const double fd = (objective(c.policy, c.m, su) - objective(c.policy, c.m, sd)) / (2 * h);
      EXPECT_NEAR(i == j ? s_bar(i, i) : s_bar(i, j) + s_bar(j, i), fd, tol) << "S " << i << j;
    }
  }
  for (int f = 0; f < 2; ++f) {
    LinearPolicy up = c.policy, down = c.policy;
    up.b(f) += h;
    down.b(f) -= h;
    EXPECT_NEAR(b_bar(f), (objective(up, c.m, c.s) - objective(down, c.m, c.s)) / (2 * h), tol);
    for (int i = 0; i < d; ++i) {
      up = c.policy;
      down = c.policy;
      up.w(f, i) += h;
      down.w(f, i) -= h;
      EXPECT_NEAR(w_bar(f, i), (objective(up, c.m, c.s) - objective(down, c.m, c.s)) / (2 * h),
                  tol) << "W " << f << "," << i;
    }
  }
}

}  // namespace linear_policy_test
}  // namespace totalgrad::pilco
