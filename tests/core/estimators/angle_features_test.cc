// (sin, cos) angle features for the particle methods (trial option
// angle_features = sincos): AngleFeatureDynamics and AngleFeaturePolicy
// (particle_system.h) against finite differences, a wrong chain rule (the
// -d/dcos sin x_a term dropped) that the checks must reject, and the whole RP
// gradient through both adapters against finite differences of J with the
// random numbers held fixed.
#include <cmath>
#include <memory>

#include <gtest/gtest.h>

#include "core/diff/gradient_checker.h"
#include "core/estimators/estimator.h"
#include "core/estimators/particle_system.h"
#include "core/estimators/rp.h"
#include "core/estimators/synthetic_problem.h"
#include "core/gp/training.h"
#include "core/gaussian/angle_features.h"

#include "tests/core/estimators/rollout_test_util.h"
namespace totalgrad::estimators {
namespace angle_features_test {

constexpr int kS = 4;      // cart-pole state
constexpr int kE = kS + 1;  // [x, u]
constexpr int kAngle = 1;  // beta

diff::CheckOptions Tight() {
  diff::CheckOptions options;
  options.relative_tolerance = 1e-5;
  options.absolute_tolerance = 1e-8;
  return options;
}

// A GP on feature inputs [phi(x), u], fitted (initial hyperparameters, as the
// synthetic problem) to the synthetic problem's cart-pole transitions.
struct FeatureModel {
  std::unique_ptr<SyntheticProblem> synthetic;
  std::unique_ptr<gp::GpModel> model;
};

FeatureModel MakeFeatureModel(const std::string& cost) {
  FeatureModel out;
  out.synthetic = ::totalgrad::estimators::testing::SmallSyntheticProblem(cost);
  const gp::GpModel& raw = *out.synthetic->model;
  RowMatrix features;
  gaussian::StatesToFeatures(raw.inputs().leftCols(kS), kAngle, &features);
  RowMatrix inputs(raw.inputs().rows(), kE + 1);
  inputs.leftCols(kE) = features;
  inputs.col(kE) = raw.inputs().col(kS);
  const RowMatrix targets = raw.targets();
  auto model = gp::GpModel::Create(inputs, targets, gp::InitialHyperparameters(inputs, targets));
  EXPECT_TRUE(model.ok()) << model.status();
  out.model = std::make_unique<gp::GpModel>(*std::move(model));
  return out;
}

// P = 3 model inputs z = [x, u] with angles where sin and cos are both large.
RowMatrix SomeInputs() {
  RowMatrix z(3, kE);
  z << 0.1, 2.2, -0.3, 1.0, 3.0,  //
      -0.4, 0.7, 0.5, -2.0, -6.0,  //
      0.3, -2.5, 0.0, 0.4, 1.5;
  return z;
}

// [mean; variance] of all particles, flattened, as a function of all inputs.
diff::VectorFunction PredictFunction(const ParticleDynamics& dynamics, Eigen::Index p) {
  return [&dynamics, p](const Vector& flat, Vector* out) {
    const RowMatrix z = Eigen::Map<const RowMatrix>(flat.data(), p, kE);
    RowMatrix mean, variance;
    dynamics.Predict(z, 1.0, &mean, &variance, nullptr, nullptr);
    out->resize(2 * p * kS);
    out->head(p * kS) = Eigen::Map<const Vector>(mean.data(), p * kS);
    out->tail(p * kS) = Eigen::Map<const Vector>(variance.data(), p * kS);
    return out->allFinite();
  };
}

// The block-diagonal Jacobian of PredictFunction from per-particle Jacobians.
Matrix AssembleJacobian(const RowMatrix& dmean_dz, const RowMatrix& dvar_dz) {
  const Eigen::Index p = dmean_dz.rows();
  Matrix j = Matrix::Zero(2 * p * kS, p * kE);
  for (Eigen::Index i = 0; i < p; ++i)
    for (int a = 0; a < kS; ++a)
      for (int m = 0; m < kE; ++m) {
        j(i * kS + a, i * kE + m) = dmean_dz(i, a * kE + m);
        j(p * kS + i * kS + a, i * kE + m) = dvar_dz(i, a * kE + m);
      }
  return j;
}

TEST(AngleFeatureDynamics, MatchesTheInnerModelOnFeaturesAndFiniteDifferences) {
  const FeatureModel fm = MakeFeatureModel("angle");
  const GpDynamics inner(fm.model.get());
  const AngleFeatureDynamics dynamics(&inner, kAngle);
  EXPECT_EQ(dynamics.state_dim(), kS);
  const RowMatrix z = SomeInputs();

  // Values: the inner model at [phi(x), u].
  RowMatrix features;
  gaussian::StatesToFeatures(z.leftCols(kS), kAngle, &features);
  RowMatrix zf(z.rows(), kE + 1);
  zf.leftCols(kE) = features;
  zf.col(kE) = z.col(kS);
  RowMatrix mean_f, var_f, dmean_f, dvar_f;
  inner.Predict(zf, 1.0, &mean_f, &var_f, &dmean_f, &dvar_f);
  RowMatrix mean, variance, dmean_dz, dvar_dz;
  dynamics.Predict(z, 1.0, &mean, &variance, &dmean_dz, &dvar_dz);
  EXPECT_EQ(mean, mean_f);
  EXPECT_EQ(variance, var_f);
  ASSERT_EQ(dmean_dz.cols(), kS * kE);
  ASSERT_EQ(dvar_dz.cols(), kS * kE);

  const Vector flat = Eigen::Map<const Vector>(z.data(), z.size());
  const diff::CheckResult r = diff::CheckJacobian(PredictFunction(dynamics, z.rows()), flat,
                                                  AssembleJacobian(dmean_dz, dvar_dz), Tight());
  EXPECT_TRUE(r.ok) << r.log;
  // The angle column must carry weight, or a wrong angle chain rule could pass.
  Eigen::Index angle_cols = 0;
  for (int a = 0; a < kS; ++a) angle_cols += dmean_dz.col(a * kE + kAngle).cwiseAbs().maxCoeff() > 1e-4;
  EXPECT_GT(angle_cols, 0);

  // A wrong chain rule: d/dx_a = d/dsin cos x_a only (the -d/dcos sin x_a
  // term dropped) must be rejected.
  RowMatrix wrong_mean = dmean_dz, wrong_var = dvar_dz;
  for (int a = 0; a < kS; ++a) {
    const int fcos = a * (kE + 1) + kS;  // column of d/dcos in the inner Jacobian
    for (Eigen::Index i = 0; i < z.rows(); ++i) {
      wrong_mean(i, a * kE + kAngle) += dmean_f(i, fcos) * std::sin(z(i, kAngle));
      wrong_var(i, a * kE + kAngle) += dvar_f(i, fcos) * std::sin(z(i, kAngle));
    }
  }
  const diff::CheckResult w = diff::CheckJacobian(PredictFunction(dynamics, z.rows()), flat,
                                                  AssembleJacobian(wrong_mean, wrong_var), Tight());
  EXPECT_FALSE(w.ok) << "a chain rule without the -d/dcos sin term must fail the check";

  // No Jacobians requested: the same values.
  RowMatrix mean2, variance2;
  dynamics.Predict(z, 1.0, &mean2, &variance2, nullptr, nullptr);
  EXPECT_EQ(mean2, mean);
  EXPECT_EQ(variance2, variance);
}

struct FeaturePolicy {
  std::unique_ptr<policy::RbfPolicy> rbf;
  std::unique_ptr<RbfParticlePolicy> inner;
  std::unique_ptr<AngleFeaturePolicy> outer;
};

FeaturePolicy MakeFeaturePolicy(const Vector& theta) {
  FeaturePolicy out;
  out.rbf = std::make_unique<policy::RbfPolicy>(6, kS + 1, 10.0);
  out.rbf->set_parameters(theta);
  out.inner = std::make_unique<RbfParticlePolicy>(out.rbf.get());
  out.outer = std::make_unique<AngleFeaturePolicy>(out.inner.get(), kAngle);
  return out;
}

Vector InitialFeaturePolicyParameters() {
  policy::RbfPolicy rbf(6, kS + 1, 10.0);
  Rng rng(9, Stream::kPolicyInit);
  Vector mean(kS + 1);
  mean << 0.0, 0.0, 0.0, 0.3, -0.5;  // [s, s_dot, beta_dot, sin, cos]
  rbf.Initialize(mean, Vector::Constant(kS + 1, 0.8), 1.0, &rng);
  // Larger weights so that the force is far from zero but not saturated.
  Vector theta = rbf.parameters();
  theta.tail(6) *= 6.0;
  return theta;
}

TEST(AngleFeaturePolicy, AdjointsMatchFiniteDifferences) {
  const Vector theta = InitialFeaturePolicyParameters();
  const FeaturePolicy fp = MakeFeaturePolicy(theta);
  const AngleFeaturePolicy& policy = *fp.outer;
  EXPECT_EQ(policy.state_dim(), kS);
  EXPECT_EQ(policy.num_parameters(), fp.rbf->num_parameters());
  const RowMatrix x = SomeInputs().leftCols(kS);
  const Eigen::Index p = x.rows();

  // Forces: the inner policy on the features.
  Vector forces, forces_f;
  PolicyCache cache;
  policy.Evaluate(x, &forces, &cache);
  RowMatrix features;
  gaussian::StatesToFeatures(x, kAngle, &features);
  fp.rbf->Evaluate(features, &forces_f, nullptr);
  EXPECT_EQ(forces, forces_f);
  EXPECT_GT(forces.cwiseAbs().minCoeff(), 0.05);

  // d force_i / d x_i, row i of the block-diagonal Jacobian (P x P*S), one
  // Backward per particle (force_bar = e_i); parameter adjoints per particle.
  Matrix analytic = Matrix::Zero(p, p * kS), wrong = Matrix::Zero(p, p * kS);
  RowMatrix per_particle = RowMatrix::Zero(p, policy.num_parameters());
  Vector param_bar = Vector::Zero(policy.num_parameters());
  for (Eigen::Index i = 0; i < p; ++i) {
    Vector force_bar = Vector::Zero(p);
    force_bar(i) = 1.0;
    RowMatrix state_bar, feature_bar;
    policy.Backward(cache, force_bar, &state_bar, nullptr, nullptr);
    fp.rbf->Backward(cache, force_bar, &feature_bar, nullptr, nullptr);
    analytic.block(i, i * kS, 1, kS) = state_bar.row(i);
    wrong.block(i, i * kS, 1, kS) = state_bar.row(i);
    wrong(i, i * kS + kAngle) += feature_bar(i, kS) * std::sin(x(i, kAngle));
  }
  const Vector ones = Vector::Ones(p);
  policy.Backward(cache, ones, nullptr, &per_particle, &param_bar);

  const diff::VectorFunction f = [&](const Vector& flat, Vector* out) {
    const RowMatrix states = Eigen::Map<const RowMatrix>(flat.data(), p, kS);
    policy.Evaluate(states, out, nullptr);
    return out->allFinite();
  };
  const Vector flat = Eigen::Map<const Vector>(x.data(), x.size());
  const diff::CheckResult r = diff::CheckJacobian(f, flat, analytic, Tight());
  EXPECT_TRUE(r.ok) << r.log;
  const diff::CheckResult w = diff::CheckJacobian(f, flat, wrong, Tight());
  EXPECT_FALSE(w.ok) << "a chain rule without the -d/dcos sin term must fail the check";

  // Parameters: row i of per_particle is d force_i / d theta; param_bar the sum.
  const diff::VectorFunction g = [&](const Vector& th, Vector* out) {
    const FeaturePolicy q = MakeFeaturePolicy(th);
    q.outer->Evaluate(x, out, nullptr);
    return out->allFinite();
  };
  const diff::CheckResult rp = diff::CheckJacobian(g, theta, Matrix(per_particle), Tight());
  EXPECT_TRUE(rp.ok) << rp.log;
  EXPECT_LT((Vector(per_particle.colwise().sum().transpose()) - param_bar).cwiseAbs().maxCoeff(), 1e-12);
}

// The whole particle problem on features: model and policy behind the adapters.
struct FeatureProblem {
  FeatureModel fm;
  std::unique_ptr<GpDynamics> inner_dynamics;
  std::unique_ptr<AngleFeatureDynamics> dynamics;
  FeaturePolicy policy;
  Problem problem;
};

std::unique_ptr<FeatureProblem> MakeFeatureProblem(const std::string& cost, const Vector& theta) {
  auto out = std::make_unique<FeatureProblem>();
  out->fm = MakeFeatureModel(cost);
  out->inner_dynamics = std::make_unique<GpDynamics>(out->fm.model.get());
  out->dynamics = std::make_unique<AngleFeatureDynamics>(out->inner_dynamics.get(), kAngle);
  out->policy = MakeFeaturePolicy(theta);
  out->problem = out->fm.synthetic->problem;  // cost, start distribution, horizon (raw state)
  out->problem.dynamics = out->dynamics.get();
  out->problem.policy = out->policy.outer.get();
  return out;
}

double FixedNoiseObjective(const FeatureProblem& base, const Vector& theta, uint64_t noise_seed,
                           int particles) {
  const FeaturePolicy q = MakeFeaturePolicy(theta);
  Problem problem = base.problem;
  problem.policy = q.outer.get();
  Rng rng(noise_seed, Stream::kParticleNoise);
  Rollout rollout;
  EXPECT_TRUE(SimulateParticles(problem, particles, {}, &rng, &rollout).ok());
  return rollout.objective;
}

class AngleFeatureRpGradient : public ::testing::TestWithParam<std::string> {};

TEST_P(AngleFeatureRpGradient, MatchesFiniteDifferencesWithFixedNoise) {
  const Vector theta = InitialFeaturePolicyParameters();
  const auto fp = MakeFeatureProblem(GetParam(), theta);
  const Problem& problem = fp->problem;
  const int particles = 5;
  Rng rng(11, Stream::kParticleNoise);
  RpEstimator rp;
  EstimateOptions eo;
  eo.particles = particles;
  GradientEstimate estimate;
  ASSERT_TRUE(rp.Estimate(problem, eo, &rng, &estimate).ok());
  ASSERT_TRUE(estimate.finite);
  ASSERT_EQ(estimate.gradient.size(), theta.size());
  EXPECT_NEAR(estimate.objective, FixedNoiseObjective(*fp, theta, 11, particles), 1e-12);
  const diff::VectorFunction f = [&](const Vector& th, Vector* out) {
    out->resize(1);
    (*out)(0) = FixedNoiseObjective(*fp, th, 11, particles);
    return std::isfinite((*out)(0));
  };
  const diff::CheckResult r =
      diff::CheckJacobian(f, theta, Matrix(estimate.gradient.transpose()), Tight());
  EXPECT_TRUE(r.ok) << r.log;
  EXPECT_GT(estimate.gradient.norm(), 1e-6) << "a zero gradient would pass trivially";
}

INSTANTIATE_TEST_SUITE_P(Costs, AngleFeatureRpGradient, ::testing::Values("angle", "tip"));

// Every particle method runs on the adapters (a finite estimate of the right size).
TEST(AngleFeatureProblem, EveryParticleMethodEstimates) {
  const Vector theta = InitialFeaturePolicyParameters();
  const auto fp = MakeFeatureProblem("angle", theta);
  for (const Method method : ParticleMethods()) {
    auto estimator = MakeEstimator(method, EstimatorOptions{});
    ASSERT_TRUE(estimator.ok()) << method << ": " << estimator.status();
    Rng rng(5, Stream::kParticleNoise);
    EstimateOptions eo;
    eo.particles = 6;
    GradientEstimate estimate;
    ASSERT_TRUE((*estimator)->Estimate(fp->problem, eo, &rng, &estimate).ok()) << method;
    EXPECT_TRUE(estimate.finite) << method;
    EXPECT_EQ(estimate.gradient.size(), theta.size()) << method;
    EXPECT_TRUE(estimate.gradient.allFinite()) << method;
  }
}

}  // namespace angle_features_test
}  // namespace totalgrad::estimators
