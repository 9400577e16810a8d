// Gaussian shaping (GLR, GTP): shaped values, exact and sampled derivatives
// of the expected cost under the fitted Gaussian, and the shaped pathwise
// pass against finite differences.
#include "core/estimators/gaussian_shaping.h"

#include <cmath>
#include <cstdio>

#include <gtest/gtest.h>

#include "core/diff/gradient_checker.h"
#include "core/estimators/synthetic_problem.h"
#include "core/estimators/total_propagation.h"
#include "core/tasks/cartpole.h"
#include "tests/core/estimators/linear_gaussian.h"

namespace totalgrad::estimators {
namespace gaussian_shaping_test {

std::unique_ptr<SyntheticProblem> SmallProblem(const std::string& cost, int horizon = 6) {
  SyntheticProblemOptions o;
  o.data = 40;
  o.horizon = horizon;
  o.basis_functions = 10;
  o.cost = cost;
  o.seed = 3;
  auto p = MakeSyntheticProblem(o);
  EXPECT_TRUE(p.ok()) << p.status();
  return *std::move(p);
}

// A fit around the upright state, so that the saturating costs have sizeable
// derivatives.
GaussianFit UprightFit(int p, uint64_t seed) {
  Rng rng(seed, Stream::kStudy);
  RowMatrix x(p, 4);
  rng.FillNormal(&x);
  Vector scale(4);
  scale << 0.3, 0.4, 0.5, 0.6;
  x = x * scale.asDiagonal();
  Vector centre(4);
  centre << 0.1, M_PI - 0.3, 0.2, -0.1;
  x.rowwise() += centre.transpose();
  GaussianFit fit;
  FitGaussian(x, kShapingJitter, &fit);
  return fit;
}

std::unique_ptr<tasks::StateCost> Cost(const std::string& name) {
  tasks::State target;
  target << 0, M_PI, 0, 0;
  auto c = tasks::MakeCost(name, target);
  EXPECT_TRUE(c.ok());
  return *std::move(c);
}

TEST(ShapedValues, SumToZeroAtEveryStep) {
  for (const std::string cost : {"angle", "tip"}) {
    auto sp = SmallProblem(cost);
    Rng rng(4, Stream::kParticleNoise);
    Rollout rollout;
    ASSERT_TRUE(SimulateParticles(sp->problem, 20, {}, &rng, &rollout).ok());
    const auto exact = sp->problem.cost->GaussianExpectation();
    ASSERT_TRUE(exact.ok());
    for (const StepRecord& step : rollout.steps) {
      GaussianFit fit;
      FitGaussian(step.next_state, kShapingJitter, &fit);
      for (bool sampled : {true, false}) {
        ExpectedCostGradient e;
        if (sampled) SampledExpectedCostGradient(*sp->problem.cost, fit, 20, &rng, &e);
        else ASSERT_TRUE(ExactExpectedCostGradient(*exact, fit, &e).ok());
        Vector g;
        ShapedValues(fit, e, &g);
        EXPECT_GT(g.cwiseAbs().sum(), 0.0);
        EXPECT_LE(std::abs(g.sum()), 1e-12 * g.cwiseAbs().sum()) << cost << " sampled " << sampled;
      }
    }
  }
}

// For c = (x - t)^T Q (x - t) the exact derivatives are e_mean = 2 Q (mean -
// t), e_cov = Q, and the shaped value is the particle's cost minus the batch
// mean of the costs: g_i = c_i - mean_j c_j.
TEST(ShapedValues, QuadraticCostGivesCostMinusBatchMean) {
  Rng rng(5, Stream::kStudy);
  RowMatrix x(9, 2);
  rng.FillNormal(&x);
  Vector t(2), q(2);
  t << 0.5, -0.2;
  q << 1.0, 3.0;
  testing::QuadraticCost cost(t, q);
  GaussianFit fit;
  FitGaussian(x, 0.0, &fit);
  ExpectedCostGradient e;
  e.dmean = 2.0 * q.asDiagonal() * (fit.mean - t);
  e.dcov = q.asDiagonal();
  Vector g, c;
  ShapedValues(fit, e, &g);
  cost.Evaluate(x, &c, nullptr);
  const Vector expected = c.array() - c.mean();
  EXPECT_LT((g - expected).cwiseAbs().maxCoeff(), 1e-12);
}

// The closed forms against central differences of themselves (mean, and the
// covariance perturbed symmetrically), and against a Monte Carlo average of
// the cost (the angle cost's closed form is exact; the tip cost's is PILCO's
// loss_cp approximation and is only required to be close).
TEST(ExactExpectedCost, DerivativesMatchFiniteDifferences) {
  const GaussianFit fit = UprightFit(40, 6);
  for (const std::string name : {"angle", "tip"}) {
    auto cost = Cost(name);
    auto gc = cost->GaussianExpectation();
    ASSERT_TRUE(gc.ok());
    ExpectedCostGradient e;
    ASSERT_TRUE(ExactExpectedCostGradient(*gc, fit, &e).ok());
    // Parameters: mean (4) then the lower triangle of cov (10).
    auto unpack = [&](const Vector& v, GaussianFit* f) {
      *f = fit;
      f->mean = v.head(4);
      int k = 4;
      for (int r = 0; r < 4; ++r)
        for (int c = 0; c <= r; ++c) f->covariance(r, c) = f->covariance(c, r) = v(k++);
    };
    Vector v(14);
    v.head(4) = fit.mean;
    Vector analytic(14);
    analytic.head(4) = e.dmean;
    int k = 4;
    for (int r = 0; r < 4; ++r)
      for (int c = 0; c <= r; ++c) {
        v(k) = fit.covariance(r, c);
        analytic(k++) = r == c ? e.dcov(r, r) : 2.0 * e.dcov(r, c);
      }
    const diff::VectorFunction f = [&](const Vector& x, Vector* out) {
      GaussianFit g;
      unpack(x, &g);
      ExpectedCostGradient eg;
      if (!ExactExpectedCostGradient(*gc, g, &eg).ok()) return false;
      out->resize(1);
      (*out)(0) = eg.value;
      return true;
    };
    const diff::CheckResult r = diff::CheckJacobian(f, v, analytic.transpose());
    EXPECT_TRUE(r.ok) << name << ": " << r.log;

    // Monte Carlo value of E[c] under the same Gaussian.
    Rng rng(7, Stream::kStudy);
    double sum = 0, sum_sq = 0;
    const int draws = 20000;
    RowMatrix z(draws, 4);
    rng.FillNormal(&z);
    RowMatrix xs = z * fit.chol.transpose();
    xs.rowwise() += fit.mean.transpose();
    Vector c;
    cost->Evaluate(xs, &c, nullptr);
    sum = c.sum();
    sum_sq = c.squaredNorm();
    const double mean = sum / draws;
    const double se = std::sqrt((sum_sq / draws - mean * mean) / draws);
    std::printf("%s: closed form %.5f, Monte Carlo %.5f +- %.5f\n", name.c_str(), e.value, mean, se);
    if (name == "angle") EXPECT_NEAR(e.value, mean, 4.5 * se);
    else EXPECT_NEAR(e.value, mean, 0.05);
  }
}

// The paper's sampled derivatives are unbiased for the exact ones (angle
// cost, whose closed form is exact): the average of R = 2000 sampled
// estimates (K = 50 draws each) agrees with the closed form entry by entry
// within 4.5 standard errors of that average.
TEST(SampledExpectedCost, AgreesWithExactOnAverage) {
  const GaussianFit fit = UprightFit(40, 8);
  auto cost = Cost("angle");
  auto gc = cost->GaussianExpectation();
  ASSERT_TRUE(gc.ok());
  ExpectedCostGradient exact;
  ASSERT_TRUE(ExactExpectedCostGradient(*gc, fit, &exact).ok());
  const int replicates = 2000;
  Vector sum = Vector::Zero(20), sum_sq = Vector::Zero(20);
  Rng rng(9, Stream::kStudy);
  for (int r = 0; r < replicates; ++r) {
    ExpectedCostGradient e;
    SampledExpectedCostGradient(*cost, fit, 50, &rng, &e);
    Vector v(20);
    v.head(4) = e.dmean;
    v.tail(16) = Eigen::Map<const Vector>(e.dcov.data(), 16);
    sum += v;
    sum_sq += v.cwiseAbs2();
  }
  Vector ref(20);
  ref.head(4) = exact.dmean;
  ref.tail(16) = Eigen::Map<const Vector>(exact.dcov.data(), 16);
  const Vector mean = sum / replicates;
  const Vector se = ((sum_sq / replicates - mean.cwiseAbs2()) / (replicates - 1)).cwiseMax(0).cwiseSqrt();
  for (int k = 0; k < 20; ++k)
    EXPECT_LE(std::abs(mean(k) - ref(k)), 4.5 * se(k) + 1e-12) << "entry " << k << " mean " << mean(k)
                                                                << " exact " << ref(k) << " se " << se(k);
  EXPECT_GT(ref.norm(), 10 * se.norm()) << "no power";
}

TEST(ExactExpectedCost, UnsupportedCostIsAnError) {
  testing::QuadraticCost cost(Vector::Zero(2), Vector::Ones(2));
  const auto gc = cost.GaussianExpectation();
  ASSERT_FALSE(gc.ok());
  EXPECT_EQ(gc.status().code(), absl::StatusCode::kInvalidArgument);
}

// GTP's pathwise part with exact derivatives is the pathwise derivative of
// J_GS(theta) = sum_t E_{N(mean_t, cov_t + jitter)}[c] over the Gaussians fitted
// to the particles, the model's random numbers held fixed: finite differences
// check the shaped cost node, its fit backward and the pass through GP and policy.
TEST(GaussianShapedPathwise, MatchesFiniteDifferencesWithFixedNoise) {
  for (const std::string name : {"angle", "tip"}) {
    auto sp = SmallProblem(name);
    const Problem& problem = sp->problem;
    const int particles = 10;
    EstimatorOptions options;
    options.gs_derivative = GsDerivative::kExact;
    options.forced_k_lr = 0.0;
    auto gtp = MakeEstimator(Method::kGtp, options);
    ASSERT_TRUE(gtp.ok());
    Rng rng(11, Stream::kParticleNoise);
    EstimateOptions eo;
    eo.particles = particles;
    GradientEstimate estimate;
    ASSERT_TRUE((*gtp)->Estimate(problem, eo, &rng, &estimate).ok());
    ASSERT_TRUE(estimate.finite);
    const auto gc = problem.cost->GaussianExpectation();
    ASSERT_TRUE(gc.ok());
    const diff::VectorFunction f = [&](const Vector& theta, Vector* out) {
      policy::RbfPolicy policy = *sp->policy;
      policy.set_parameters(theta);
      const RbfParticlePolicy adapter(&policy);
      Problem pr = problem;
      pr.policy = &adapter;
      Rng r(11, Stream::kParticleNoise);
      Rollout rollout;
      if (!SimulateParticles(pr, particles, {}, &r, &rollout).ok()) return false;
      double j = 0;
      for (const StepRecord& step : rollout.steps) {
        GaussianFit fit;
        FitGaussian(step.next_state, kShapingJitter, &fit);
        ExpectedCostGradient e;
        if (!ExactExpectedCostGradient(*gc, fit, &e).ok()) return false;
        j += e.value;
      }
      out->resize(1);
      (*out)(0) = j;
      return true;
    };
    diff::CheckOptions check;
    check.relative_tolerance = 1e-5;
    check.absolute_tolerance = 1e-8;
    const diff::CheckResult r =
        diff::CheckJacobian(f, sp->policy->parameters(), estimate.gradient.transpose(), check);
    EXPECT_TRUE(r.ok) << name << ": " << r.log;
    EXPECT_GT(estimate.gradient.norm(), 1e-6);
  }
}

}  // namespace gaussian_shaping_test
}  // namespace totalgrad::estimators
