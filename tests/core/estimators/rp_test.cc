#include "core/estimators/rp.h"

#include <cmath>

#include <gtest/gtest.h>

#include "core/diff/gradient_checker.h"
#include "core/estimators/synthetic_problem.h"

#include "tests/core/estimators/rollout_test_util.h"

namespace totalgrad::estimators {
namespace rp_test {

std::unique_ptr<SyntheticProblem> SmallProblem(const std::string& cost) {
  return ::totalgrad::estimators::testing::SmallSyntheticProblem(cost);
}

double Objective(const SyntheticProblem& base, const Vector& theta, uint64_t noise_seed, int particles) {
  return ::totalgrad::estimators::testing::FixedNoiseObjective(base.problem, *base.policy, theta,
                                                                noise_seed, particles);
}

class RpGradient : public ::testing::TestWithParam<std::string> {};

TEST_P(RpGradient, MatchesFiniteDifferencesWithFixedNoise) {
  auto sp = SmallProblem(GetParam());
  const Problem& problem = sp->problem;
  const int particles = 5;
  Rng rng(11, Stream::kParticleNoise);
  RpEstimator rp;
  EstimateOptions eo;
  eo.particles = particles;
  eo.keep_per_particle = true;
  GradientEstimate estimate;
  ASSERT_TRUE(rp.Estimate(problem, eo, &rng, &estimate).ok());
  ASSERT_TRUE(estimate.finite);
  EXPECT_NEAR(estimate.objective, Objective(*sp, sp->policy->parameters(), 11, particles), 1e-12);

  const diff::VectorFunction f = [&](const Vector& theta, Vector* out) {
    out->resize(1);
    (*out)(0) = Objective(*sp, theta, 11, particles);
    return std::isfinite((*out)(0));
  };
  diff::CheckOptions options;
  options.relative_tolerance = 1e-5;
  options.absolute_tolerance = 1e-8;
  const Matrix analytic = estimate.gradient.transpose();
  const diff::CheckResult r = diff::CheckJacobian(f, sp->policy->parameters(), analytic, options);
  EXPECT_TRUE(r.ok) << r.log;
  EXPECT_GT(estimate.gradient.norm(), 1e-6) << "a zero gradient would pass trivially";

  // Per-particle gradients average to the estimate.
  ASSERT_EQ(estimate.per_particle.rows(), particles);
  EXPECT_LT((estimate.per_particle.colwise().mean().transpose() - estimate.gradient).cwiseAbs().maxCoeff(),
            1e-12);
}

INSTANTIATE_TEST_SUITE_P(Costs, RpGradient, ::testing::Values("angle", "tip"));

// Dropping the path through the predictive variance gives a wrong gradient,
// and the finite-difference check must notice.
TEST(RpGradientCheck, IgnoringTheVariancePathFails) {
  auto sp = SmallProblem("angle");
  const Problem& problem = sp->problem;
  Rng rng(11, Stream::kParticleNoise);
  Rollout rollout;
  ASSERT_TRUE(SimulateParticles(problem, 5, {true}, &rng, &rollout).ok());
  for (StepRecord& step : rollout.steps) step.dvar_dz.setZero();
  Vector wrong;
  RpBackward(problem, rollout, &wrong, nullptr);
  const diff::VectorFunction f = [&](const Vector& theta, Vector* out) {
    out->resize(1);
    (*out)(0) = Objective(*sp, theta, 11, 5);
    return true;
  };
  diff::CheckOptions options;
  options.relative_tolerance = 1e-5;
  EXPECT_FALSE(diff::CheckJacobian(f, sp->policy->parameters(), wrong.transpose(), options).ok);
}

// The RP gradient through PILCO's linear policy (LinearParticlePolicy): the
// synthetic cart-pole problem with its RBF policy replaced by a linear one
// (S = 4, one force bounded by 10), against central differences of the
// fixed-noise objective.
TEST(RpGradientLinearPolicy, MatchesFiniteDifferencesWithFixedNoise) {
  auto sp = SmallProblem("tip");
  policy::LinearPolicy linear(4, Vector::Constant(1, 10.0));
  Rng init(5, Stream::kPolicyInit);
  linear.Initialize(0.5, &init);
  const int particles = 5;
  auto objective = [&](const Vector& theta) {
    policy::LinearPolicy moved = linear;
    moved.set_parameters(theta);
    const LinearParticlePolicy adapter(&moved);
    Problem problem = sp->problem;
    problem.policy = &adapter;
    Rng rng(11, Stream::kParticleNoise);
    Rollout rollout;
    EXPECT_TRUE(SimulateParticles(problem, particles, {}, &rng, &rollout).ok());
    return rollout.objective;
  };
  const LinearParticlePolicy adapter(&linear);
  Problem problem = sp->problem;
  problem.policy = &adapter;
  Rng rng(11, Stream::kParticleNoise);
  RpEstimator rp;
  EstimateOptions eo;
  eo.particles = particles;
  GradientEstimate estimate;
  ASSERT_TRUE(rp.Estimate(problem, eo, &rng, &estimate).ok());
  ASSERT_EQ(estimate.gradient.size(), 5);
  EXPECT_NEAR(estimate.objective, objective(linear.parameters()), 1e-12);
  const diff::VectorFunction f = [&](const Vector& theta, Vector* out) {
    *out = Vector::Constant(1, objective(theta));
    return std::isfinite((*out)(0));
  };
  diff::CheckOptions options;
  options.relative_tolerance = 1e-5;
  options.absolute_tolerance = 1e-8;
  const diff::CheckResult r =
      diff::CheckJacobian(f, linear.parameters(), estimate.gradient.transpose(), options);
  EXPECT_TRUE(r.ok) << r.log;
  EXPECT_GT(estimate.gradient.norm(), 1e-6) << "a zero gradient would pass trivially";
}

TEST(ColumnSampleVariance, MatchesDefinition) {
  RowMatrix m(3, 2);
  m << 1, 2, 3, 2, 5, 2;
  const Vector v = ColumnSampleVariance(m);
  EXPECT_DOUBLE_EQ(v(0), 4.0);  // mean 3, squares 4+0+4 over 2
  EXPECT_DOUBLE_EQ(v(1), 0.0);
  EXPECT_EQ(ColumnSampleVariance(m.topRows(1)).norm(), 0.0);
}

TEST(MakeEstimator, UnknownMethodIsNamed) {
  // Names are parsed once, at the edge (estimators/method.h).
  auto e = ParseMethod("XYZ");
  ASSERT_FALSE(e.ok());
  EXPECT_NE(e.status().message().find("XYZ"), std::string::npos);
}

}  // namespace rp_test
}  // namespace totalgrad::estimators
