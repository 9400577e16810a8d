// The moment-matched step with PILCO's linear policy (PolicyClass::kLinear):
// J and dJ/d[W, b] against central differences in the unicycle's shape (the
// GP on 9 of the 10 predicted entries, both torques, the unicycle cost) and
// on the shared-input path with one control; the control moments of the
// step are the linear policy's own; bad options are refused.
#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <vector>

#include <Eigen/Eigenvalues>

#include "core/diff/gradient_checker.h"
#include "core/gaussian/expected_cost.h"
#include "core/pilco/linear_policy.h"
#include "core/pilco/propagation.h"
#include "core/tasks/unicycle.h"
#include "tests/core/pilco/pilco_test_util.h"

namespace totalgrad::pilco {
namespace linear_propagation_test {

// Central differences of J(params) against PredictTrajectory's gradient.
void ExpectGradientMatchesCentralDifferences(const Propagator& prop,
                                             const gaussian::GaussianCost& cost,
                                             const Vector& params, const Vector& mu0,
                                             const Matrix& s0, int horizon) {
  Trajectory tr;
  Vector grad;
  const absl::Status st = PredictTrajectory(prop, cost, params, mu0, s0, horizon, &tr, &grad);
  ASSERT_TRUE(st.ok()) << st;
  ASSERT_EQ(grad.size(), prop.num_parameters());
  for (const Matrix& s : tr.covs) {
    EXPECT_LT((s - s.transpose()).cwiseAbs().maxCoeff(), 1e-12);
    EXPECT_GT(Eigen::SelfAdjointEigenSolver<Matrix>(s).eigenvalues().minCoeff(), -1e-10);
  }
  const diff::VectorFunction j = [&](const Vector& th, Vector* out) {
    Trajectory t;
    if (!PredictTrajectory(prop, cost, th, mu0, s0, horizon, &t, nullptr).ok()) return false;
    *out = Vector::Constant(1, t.total_cost);
    return true;
  };
  diff::CheckOptions check;
  check.relative_step = 1e-6;
  check.relative_tolerance = 1e-5;
  check.absolute_tolerance = 1e-8;
  const diff::CheckResult r = diff::CheckJacobian(j, params, grad.transpose(), check);
  EXPECT_TRUE(r.ok) << r.log;
  // Every parameter matters: no block of the gradient is silently zero.
  const int f = prop.control_dim(), ep = prop.policy_input_dim();
  EXPECT_GT(grad.head(f * ep).cwiseAbs().maxCoeff(), 1e-5) << "dJ/dW";
  EXPECT_GT(grad.tail(f).cwiseAbs().maxCoeff(), 1e-5) << "dJ/db";
}

// The unicycle's sets (0-based, into its 10-entry GP state): the policy
// reads all 10 entries, the GP 9 (not the yaw, entry 8), no angle through
// sin/cos; two torques bounded by [10, 50] N m.
TEST(LinearPropagationTest, UnicycleShapeGradientMatchesCentralDifferences) {
  const int d = tasks::kUnicycleCostStateDim, f = 2;
  const std::vector<int> dyni = {0, 1, 2, 3, 4, 5, 6, 7, 9};
  std::vector<int> poli(d);
  for (int i = 0; i < d; ++i) poli[i] = i;
  std::mt19937_64 rng(71);
  const GaussianInputGp gp =
      testing::MakeTestGp(40, static_cast<int>(dyni.size()) + f, d, &rng, 1.5);
  PropagationOptions options;
  options.policy_class = PolicyClass::kLinear;
  options.policy_inputs = poli;
  options.dynamics_inputs = dyni;
  options.max_controls = Eigen::Vector2d(10.0, 50.0);
  ASSERT_TRUE(Propagator::Validate(gp, options).ok()) << Propagator::Validate(gp, options);
  const Propagator prop(&gp, options);
  ASSERT_EQ(prop.num_parameters(), f * d + f);
  Vector params = testing::RandomVector(prop.num_parameters(), 0.05, &rng);
  // Column-major W then b: W(1, 3) is entry 1 + 3 F.
  params(1 + 3 * f) = 0.2;
  const LinearPolicy policy = prop.LinearPolicyOf(params);
  EXPECT_EQ(policy.w(1, 3), 0.2);
  EXPECT_EQ(policy.b(1), params(f * d + 1));
  EXPECT_EQ(policy.max_u(1), 50.0);
  const Vector mu0 = testing::RandomVector(d, 0.1, &rng);
  const Matrix s0 = testing::RandomCovariance(d, 0.02, &rng);
  absl::StatusOr<gaussian::GaussianCost> cost = tasks::UnicycleCost();
  ASSERT_TRUE(cost.ok()) << cost.status();
  ExpectGradientMatchesCentralDifferences(prop, *cost, params, mu0, s0, 8);
}

// One control on the shared path (the GP sees [p; u], p the whole state):
// the linear policy also takes the joint step form there.
TEST(LinearPropagationTest, OneControlSharedInputsGradientMatchesCentralDifferences) {
  const int d = 3;
  std::mt19937_64 rng(72);
  const GaussianInputGp gp = testing::MakeTestGp(30, d + 1, d, &rng, 1.2);
  PropagationOptions options;
  options.policy_class = PolicyClass::kLinear;
  options.max_force = 3.0;
  ASSERT_TRUE(Propagator::Validate(gp, options).ok()) << Propagator::Validate(gp, options);
  const Propagator prop(&gp, options);
  ASSERT_EQ(prop.num_parameters(), d + 1);
  const Vector params = testing::RandomVector(d + 1, 0.5, &rng);
  const Vector mu0 = testing::RandomVector(d, 0.3, &rng);
  const Matrix s0 = testing::RandomCovariance(d, 0.05, &rng);
  absl::StatusOr<gaussian::GaussianCost> cost = gaussian::GaussianCost::Saturating(
      d, std::vector<int>{}, Matrix::Identity(d, d), Vector::Zero(d), {1.0});
  ASSERT_TRUE(cost.ok()) << cost.status();
  ExpectGradientMatchesCentralDifferences(prop, *cost, params, mu0, s0, 10);
}

// The step's control moments are LinearPolicyForward's at the policy input:
// the GP's input g = [p; u] carries E[u], Cov[u] and Cov(p, u) = S W^T diag(c).
TEST(LinearPropagationTest, StepCarriesTheLinearPolicysMoments) {
  const int d = 3;
  std::mt19937_64 rng(73);
  const GaussianInputGp gp = testing::MakeTestGp(30, d + 2, d, &rng, 1.2);
  PropagationOptions options;
  options.policy_class = PolicyClass::kLinear;
  options.max_controls = Eigen::Vector2d(2.0, 5.0);
  const Propagator prop(&gp, options);
  const Vector params = testing::RandomVector(prop.num_parameters(), 0.7, &rng);
  const Vector m = testing::RandomVector(d, 0.3, &rng);
  const Matrix s = testing::RandomCovariance(d, 0.1, &rng);
  StepCache cache;
  Vector m_next;
  Matrix s_next;
  ASSERT_TRUE(prop.Step(params, m, s, &m_next, &s_next, &cache).ok());
  LinearPolicyMoments expected;
  LinearPolicyForward(prop.LinearPolicyOf(params), m, s, &expected);
  EXPECT_EQ(cache.g_mean.tail(2), expected.mean);
  EXPECT_EQ(Matrix(cache.g_cov.bottomRightCorner(2, 2)), expected.cov);
  EXPECT_LT((cache.g_cov.topRightCorner(d, 2) - expected.cross).cwiseAbs().maxCoeff(), 1e-14);
  EXPECT_GT(expected.cov.cwiseAbs().maxCoeff(), 1e-3) << "the controls should be uncertain";
}

TEST(LinearPropagationTest, LengthscalesPerControlAreRefused) {
  std::mt19937_64 rng(74);
  const GaussianInputGp gp = testing::MakeTestGp(10, 4, 2, &rng);
  PropagationOptions options;
  options.policy_class = PolicyClass::kLinear;
  options.max_controls = Eigen::Vector2d(1.0, 1.0);
  options.policy_lengthscale_per_control = true;
  const absl::Status st = Propagator::Validate(gp, options);
  EXPECT_EQ(st.code(), absl::StatusCode::kInvalidArgument);
  EXPECT_NE(st.message().find("linear policy has no length-scales"), std::string::npos) << st;
}

}  // namespace linear_propagation_test
}  // namespace totalgrad::pilco
