// Particle rollouts through a sparse GP (FitcDynamics over gp::FitcModel, the
// model a trial uses with gp_inducing): the whole RP gradient against finite
// differences of J with the random numbers held fixed, and a wrong gradient
// (the variance path dropped) that the check must reject.
#include <cmath>

#include <gtest/gtest.h>

#include "core/diff/gradient_checker.h"
#include "core/estimators/estimator.h"
#include "core/estimators/particle_system.h"
#include "core/estimators/rp.h"
#include "core/estimators/synthetic_problem.h"
#include "core/gp/fitc.h"

#include "tests/core/estimators/rollout_test_util.h"

namespace totalgrad::estimators {
namespace fitc_rollout_test {

// The synthetic problem (N = 40 transitions) with its GP replaced by FITC on
// M = 12 inducing inputs drawn from the data.
struct SparseProblem {
  std::unique_ptr<SyntheticProblem> synthetic;
  std::unique_ptr<gp::FitcModel> fitc;
  std::unique_ptr<FitcDynamics> dynamics;
  Problem problem;
};

SparseProblem MakeSparseProblem(const std::string& cost) {
  SparseProblem out;
  out.synthetic = ::totalgrad::estimators::testing::SmallSyntheticProblem(cost);
  const gp::GpModel& full = *out.synthetic->model;
  Rng rng(4, Stream::kGpInit);
  auto fitc = gp::FitcModel::Create(full.inputs(), full.targets(), full.hyperparameters(),
                                    gp::RandomSubsetOfInputs(full.inputs(), 12, &rng));
  EXPECT_TRUE(fitc.ok()) << fitc.status();
  out.fitc = std::make_unique<gp::FitcModel>(*std::move(fitc));
  out.dynamics = std::make_unique<FitcDynamics>(out.fitc.get());
  out.problem = out.synthetic->problem;
  out.problem.dynamics = out.dynamics.get();  // as a trial with gp_inducing sets it up
  return out;
}

double Objective(const SparseProblem& sp, const Problem& base, const Vector& theta,
                 uint64_t noise_seed, int particles) {
  return ::totalgrad::estimators::testing::FixedNoiseObjective(base, *sp.synthetic->policy, theta,
                                                                noise_seed, particles);
}

diff::CheckOptions GradientCheckOptions() {
  diff::CheckOptions options;
  options.relative_tolerance = 1e-5;
  options.absolute_tolerance = 1e-8;
  return options;
}

class FitcRpGradient : public ::testing::TestWithParam<std::string> {};

TEST_P(FitcRpGradient, MatchesFiniteDifferencesWithFixedNoise) {
  const SparseProblem sp = MakeSparseProblem(GetParam());
  const Problem& problem = sp.problem;
  const int particles = 5;
  Rng rng(11, Stream::kParticleNoise);
  auto rp = MakeEstimator(Method::kRp, {});
  ASSERT_TRUE(rp.ok());
  EstimateOptions eo;
  eo.particles = particles;
  GradientEstimate estimate;
  ASSERT_TRUE((*rp)->Estimate(problem, eo, &rng, &estimate).ok());
  ASSERT_TRUE(estimate.finite);
  const Vector theta = sp.synthetic->policy->parameters();
  EXPECT_NEAR(estimate.objective, Objective(sp, problem, theta, 11, particles), 1e-12);
  // The sparse model is really the one used: J differs from the full GP's.
  EXPECT_GT(std::abs(estimate.objective - Objective(sp, sp.synthetic->problem, theta, 11, particles)),
            1e-6);

  const diff::VectorFunction f = [&](const Vector& t, Vector* out) {
    out->resize(1);
    (*out)(0) = Objective(sp, problem, t, 11, particles);
    return std::isfinite((*out)(0));
  };
  const diff::CheckResult r =
      diff::CheckJacobian(f, theta, estimate.gradient.transpose(), GradientCheckOptions());
  EXPECT_TRUE(r.ok) << r.log;
  EXPECT_GT(estimate.gradient.norm(), 1e-6) << "a zero gradient would pass trivially";
}

INSTANTIATE_TEST_SUITE_P(Costs, FitcRpGradient, ::testing::Values("angle", "tip"));

TEST(FitcRpGradientCheck, IgnoringTheVariancePathFails) {
  const SparseProblem sp = MakeSparseProblem("angle");
  const Problem& problem = sp.problem;
  Rng rng(11, Stream::kParticleNoise);
  Rollout rollout;
  ASSERT_TRUE(SimulateParticles(problem, 5, {true}, &rng, &rollout).ok());
  for (StepRecord& step : rollout.steps) {
    ASSERT_GT(step.dvar_dz.cwiseAbs().maxCoeff(), 0.0);
    step.dvar_dz.setZero();
  }
  Vector wrong;
  RpBackward(problem, rollout, &wrong, nullptr);
  const diff::VectorFunction f = [&](const Vector& t, Vector* out) {
    out->resize(1);
    (*out)(0) = Objective(sp, problem, t, 11, 5);
    return true;
  };
  EXPECT_FALSE(
      diff::CheckJacobian(f, sp.synthetic->policy->parameters(), wrong.transpose(), GradientCheckOptions())
          .ok);
}

}  // namespace fitc_rollout_test
}  // namespace totalgrad::estimators
