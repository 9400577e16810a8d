// The particle estimators with F = 2 controls, on the double pendulum's
// layout (4 states, angles 2 and 3, two torques): a GP on [phi(x), u1, u2]
// fitted to transitions of the real plant, and an RBF policy with two outputs
// on phi(x), both behind the angle-feature adapters as a trial builds them;
// a quadratic cost.
//  * the adapters' derivatives with two control columns against finite
//    differences;
//  * the RP gradient against finite differences of J with the random numbers
//    held fixed;
//  * TP at k_LR forced to 0 and 1 is RP and LR bit for bit (GTP at 1 is GLR);
//  * every particle method gives finite estimates whose per-particle rows
//    average to the gradient, TP's weights in [0, 1];
//  * TP's adaptive combination with F > 1 (which forms both branches'
//    per-particle rows) gives the one-control pass's numbers on a system
//    whose second control is inert.
// That RP, LR and TP agree with the exact gradient in expectation with F = 2
// is in linear_gaussian_test.cc (TwoControls).
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <memory>
#include <string>
#include <vector>

#include "core/common/rng.h"
#include "core/diff/gradient_checker.h"
#include "core/estimators/estimator.h"
#include "core/estimators/particle_system.h"
#include "core/estimators/rp.h"
#include "core/estimators/total_propagation.h"
#include "core/gp/training.h"
#include "core/gaussian/angle_features.h"
#include "core/tasks/scene.h"
#include "tests/core/estimators/linear_gaussian.h"

namespace totalgrad::estimators {
namespace multi_control_test {

constexpr int kS = 4;                     // [dtheta1, dtheta2, theta1, theta2]
const std::vector<int> kAngles = {2, 3};  // the double pendulum's
constexpr int kFeat = kS + 2;             // phi(x): 2 velocities, (sin, cos) x 2
constexpr int kF = 2;                     // two torques
constexpr int kE = kS + kF;               // raw model inputs [x, u1, u2]
constexpr int kBasis = 6;

diff::CheckOptions Tight() {
  diff::CheckOptions options;
  options.relative_tolerance = 1e-5;
  options.absolute_tolerance = 1e-8;
  return options;
}

// Everything a two-control problem owns; `problem` points into it.
struct TwoControlProblem {
  tasks::Scene scene;
  std::unique_ptr<gp::GpModel> model;
  std::unique_ptr<GpDynamics> inner_dynamics;
  std::unique_ptr<AngleFeatureDynamics> dynamics;
  std::unique_ptr<policy::RbfPolicy> rbf;
  std::unique_ptr<RbfParticlePolicy> inner_policy;
  std::unique_ptr<AngleFeaturePolicy> policy;
  std::unique_ptr<testing::QuadraticCost> cost;
  Problem problem;
};

std::unique_ptr<TwoControlProblem> MakeTwoControlProblem(int horizon) {
  auto out = std::make_unique<TwoControlProblem>();
  tasks::SceneOptions so;
  so.scene = "double-pendulum";
  absl::StatusOr<tasks::Scene> scene = tasks::MakeScene(so);
  EXPECT_TRUE(scene.ok()) << scene.status();
  out->scene = *std::move(scene);
  EXPECT_EQ(out->scene.control_dim(), kF);
  // 60 transitions of the real plant from states spread around the start
  // (hanging, pi) and torques uniform in their bounds: GP inputs [phi(x), u].
  const int n = 60;
  Rng rng(17, Stream::kStudy);
  RowMatrix x(n, kS), u(n, kF), next(n, kS);
  for (int i = 0; i < n; ++i) {
    for (int m = 0; m < kS; ++m) x(i, m) = out->scene.mu0(m) + (m < 2 ? 2.0 : 0.8) * rng.Normal();
    for (int j = 0; j < kF; ++j) u(i, j) = rng.Uniform(-out->scene.max_control(j), out->scene.max_control(j));
    Vector xn;
    EXPECT_TRUE(out->scene.plant->Step(x.row(i).transpose(), u.row(i).transpose(), &xn).ok());
    next.row(i) = xn.transpose();
  }
  RowMatrix features;
  gaussian::StatesToFeatures(x, kAngles, &features);
  RowMatrix inputs(n, kFeat + kF);
  inputs.leftCols(kFeat) = features;
  inputs.rightCols(kF) = u;
  const RowMatrix targets = next - x;
  auto model = gp::GpModel::Create(inputs, targets, gp::InitialHyperparameters(inputs, targets));
  EXPECT_TRUE(model.ok()) << model.status();
  out->model = std::make_unique<gp::GpModel>(*std::move(model));
  out->inner_dynamics = std::make_unique<GpDynamics>(out->model.get());
  out->dynamics = std::make_unique<AngleFeatureDynamics>(out->inner_dynamics.get(), kAngles);

  // Policy on phi(x) with two outputs, weights large enough that the
  // torques are far from zero and the saturation's curvature matters.
  out->rbf = std::make_unique<policy::RbfPolicy>(kBasis, kFeat, out->scene.max_control);
  Rng init(18, Stream::kPolicyInit);
  const Vector mu_features = gaussian::StateFeatures(out->scene.mu0, kAngles);
  out->rbf->Initialize(mu_features, Vector::Constant(kFeat, 0.8), 1.0, &init);
  Vector theta = out->rbf->parameters();
  theta.tail(kBasis * kF) *= 6.0;
  out->rbf->set_parameters(theta);
  out->inner_policy = std::make_unique<RbfParticlePolicy>(out->rbf.get());
  out->policy = std::make_unique<AngleFeaturePolicy>(out->inner_policy.get(), kAngles);

  // A quadratic cost towards a state near the start: the scene's costs are
  // flat (~1) around the hanging start, which would leave the gradients too
  // small for the finite-difference checks to mean anything.
  Vector target(kS), q(kS);
  target << 0.0, 0.0, M_PI - 0.5, M_PI + 0.4;
  q << 0.05, 0.05, 1.0, 1.0;
  out->cost = std::make_unique<testing::QuadraticCost>(target, q);

  Problem& p = out->problem;
  p.dynamics = out->dynamics.get();
  p.policy = out->policy.get();
  p.cost = out->cost.get();
  p.mu0 = out->scene.mu0;
  p.initial_std = out->scene.initial_std;
  p.horizon = horizon;
  return out;
}

// J(theta) with the random numbers of `noise_seed` held fixed.
double FixedNoiseObjective(const TwoControlProblem& base, const Vector& theta, uint64_t noise_seed,
                           int particles) {
  policy::RbfPolicy rbf = *base.rbf;
  rbf.set_parameters(theta);
  const RbfParticlePolicy inner(&rbf);
  const AngleFeaturePolicy policy(&inner, kAngles);
  Problem problem = base.problem;
  problem.policy = &policy;
  Rng rng(noise_seed, Stream::kParticleNoise);
  Rollout rollout;
  EXPECT_TRUE(SimulateParticles(problem, particles, {}, &rng, &rollout).ok());
  return rollout.objective;
}

std::unique_ptr<Estimator> MakeByName(const std::string& name, const EstimatorOptions& options = {}) {
  absl::StatusOr<Method> method = ParseMethod(name);
  EXPECT_TRUE(method.ok()) << method.status();
  auto e = MakeEstimator(*method, options);
  EXPECT_TRUE(e.ok()) << e.status();
  return e.ok() ? *std::move(e) : nullptr;
}

GradientEstimate RunMethod(const std::string& method, const EstimatorOptions& options,
                           const Problem& problem, int particles, uint64_t seed) {
  std::unique_ptr<Estimator> e = MakeByName(method, options);
  Rng rng(seed, Stream::kParticleNoise);
  EstimateOptions eo;
  eo.particles = particles;
  eo.keep_per_particle = true;
  GradientEstimate estimate;
  const absl::Status st = e->Estimate(problem, eo, &rng, &estimate);
  EXPECT_TRUE(st.ok()) << method << ": " << st;
  return estimate;
}

TEST(TwoControls, RolloutShapes) {
  auto tc = MakeTwoControlProblem(3);
  ASSERT_EQ(tc->problem.policy->control_dim(), kF);
  ASSERT_EQ(tc->problem.dynamics->input_dim(), kE);
  Rng rng(1, Stream::kParticleNoise);
  RolloutRecording rec;
  rec.jacobians = true;
  Rollout rollout;
  TG_CHECK(SimulateParticles(tc->problem, 5, rec, &rng, &rollout).ok());
  for (const StepRecord& step : rollout.steps) {
    EXPECT_EQ(step.force.size(), 5 * kF);
    EXPECT_EQ(step.dmean_dz.cols(), kS * kE);
    // Both torques act: neither column of the control Jacobian vanishes.
    for (int j = 0; j < kF; ++j) {
      double largest = 0;
      for (int a = 0; a < kS; ++a)
        largest = std::max(largest, step.dmean_dz.col(a * kE + kS + j).cwiseAbs().maxCoeff());
      EXPECT_GT(largest, 1e-4) << "torque " << j;
    }
  }
  // A dynamics model whose inputs are not S + F is refused, naming the shapes.
  Problem wrong = tc->problem;
  const testing::LinearDynamics one_control(Matrix::Zero(kS, kS), Vector::Ones(kS), Vector::Zero(kS),
                                            Vector::Constant(kS, 0.01));
  wrong.dynamics = &one_control;
  EXPECT_EQ(SimulateParticles(wrong, 5, rec, &rng, &rollout).code(), absl::StatusCode::kInvalidArgument);
}

TEST(TwoControls, FeatureDynamicsJacobiansMatchFiniteDifferences) {
  auto tc = MakeTwoControlProblem(3);
  const ParticleDynamics& dynamics = *tc->problem.dynamics;
  RowMatrix z(3, kE);
  z << 0.5, -1.0, 2.9, 3.6, 1.2, -0.7,  //
      -2.0, 0.3, 3.5, 2.5, -1.5, 1.9,  //
      1.0, 1.5, 3.1, 3.0, 0.2, 0.4;
  const Eigen::Index p = z.rows();
  RowMatrix mean, variance, dmean, dvar;
  dynamics.Predict(z, 1.0, &mean, &variance, &dmean, &dvar);
  ASSERT_EQ(dmean.cols(), kS * kE);
  const diff::VectorFunction f = [&](const Vector& flat, Vector* out) {
    const RowMatrix zz = Eigen::Map<const RowMatrix>(flat.data(), p, kE);
    RowMatrix m, v;
    dynamics.Predict(zz, 1.0, &m, &v, nullptr, nullptr);
    out->resize(2 * p * kS);
    out->head(p * kS) = Eigen::Map<const Vector>(m.data(), p * kS);
    out->tail(p * kS) = Eigen::Map<const Vector>(v.data(), p * kS);
    return out->allFinite();
  };
  auto assemble = [&](const RowMatrix& dm, const RowMatrix& dv) {
    Matrix j = Matrix::Zero(2 * p * kS, p * kE);
    for (Eigen::Index i = 0; i < p; ++i)
      for (int a = 0; a < kS; ++a)
        for (int m = 0; m < kE; ++m) {
          j(i * kS + a, i * kE + m) = dm(i, a * kE + m);
          j(p * kS + i * kS + a, i * kE + m) = dv(i, a * kE + m);
        }
    return j;
  };
  const Vector flat = Eigen::Map<const Vector>(z.data(), z.size());
  const diff::CheckResult r = diff::CheckJacobian(f, flat, assemble(dmean, dvar), Tight());
  EXPECT_TRUE(r.ok) << r.log;
  // The two torque columns swapped: caught.
  RowMatrix swapped = dmean;
  for (int a = 0; a < kS; ++a) {
    swapped.col(a * kE + kS).swap(swapped.col(a * kE + kS + 1));
  }
  EXPECT_FALSE(diff::CheckJacobian(f, flat, assemble(swapped, dvar), Tight()).ok);
}

TEST(TwoControls, FeaturePolicyAdjointsMatchFiniteDifferences) {
  auto tc = MakeTwoControlProblem(3);
  const ParticlePolicy& policy = *tc->problem.policy;
  RowMatrix x(3, kS);
  x << 0.5, -1.0, 2.9, 3.6,  //
      -2.0, 0.3, 3.5, 2.5,  //
      1.0, 1.5, 3.1, 3.0;
  const Eigen::Index p = x.rows();
  Vector u;
  PolicyCache cache;
  policy.Evaluate(x, &u, &cache);
  ASSERT_EQ(u.size(), p * kF);
  // A general force_bar: state_bar row i = sum_j fb_ij du_ij/dx_i.
  Vector fb(p * kF);
  fb << 0.7, -1.3, 0.4, 2.0, -0.6, 0.9;
  RowMatrix state_bar;
  const int n = policy.num_parameters();
  RowMatrix per_particle = RowMatrix::Zero(p, n);
  Vector summed = Vector::Zero(n);
  policy.Backward(cache, fb, &state_bar, &per_particle, &summed);
  for (Eigen::Index i = 0; i < p; ++i) {
    const diff::VectorFunction f = [&](const Vector& xi, Vector* out) {
      Vector ui;
      policy.Evaluate(xi.transpose(), &ui, nullptr);
      out->resize(1);
      (*out)(0) = fb.segment(i * kF, kF).dot(ui);
      return true;
    };
    const diff::CheckResult r =
        diff::CheckJacobian(f, x.row(i).transpose(), Matrix(state_bar.row(i)), Tight());
    EXPECT_TRUE(r.ok) << "particle " << i << ": " << r.log;
  }
  // Parameters: sum_i sum_j fb_ij du_ij/dtheta.
  const diff::VectorFunction g = [&](const Vector& theta, Vector* out) {
    policy::RbfPolicy rbf = *tc->rbf;
    rbf.set_parameters(theta);
    const RbfParticlePolicy inner(&rbf);
    const AngleFeaturePolicy outer(&inner, kAngles);
    Vector uu;
    outer.Evaluate(x, &uu, nullptr);
    out->resize(1);
    (*out)(0) = fb.dot(uu);
    return true;
  };
  const diff::CheckResult r = diff::CheckJacobian(g, tc->rbf->parameters(), Matrix(summed.transpose()), Tight());
  EXPECT_TRUE(r.ok) << r.log;
  EXPECT_LT((per_particle.colwise().sum().transpose() - summed).cwiseAbs().maxCoeff(), 1e-12);
}

TEST(TwoControls, RpGradientMatchesFiniteDifferencesWithFixedNoise) {
  auto tc = MakeTwoControlProblem(6);
  const int particles = 5;
  Rng rng(11, Stream::kParticleNoise);
  RpEstimator rp;
  EstimateOptions eo;
  eo.particles = particles;
  GradientEstimate estimate;
  ASSERT_TRUE(rp.Estimate(tc->problem, eo, &rng, &estimate).ok());
  ASSERT_TRUE(estimate.finite);
  EXPECT_NEAR(estimate.objective, FixedNoiseObjective(*tc, tc->rbf->parameters(), 11, particles), 1e-12);
  const diff::VectorFunction f = [&](const Vector& theta, Vector* out) {
    out->resize(1);
    (*out)(0) = FixedNoiseObjective(*tc, theta, 11, particles);
    return std::isfinite((*out)(0));
  };
  const diff::CheckResult r =
      diff::CheckJacobian(f, tc->rbf->parameters(), Matrix(estimate.gradient.transpose()), Tight());
  EXPECT_TRUE(r.ok) << r.log;
  // Both torques' weights carry gradient (a pass that dropped the second
  // control's cotangent would leave its weights at zero and fail above).
  const int w0 = kBasis * kFeat + kFeat;
  for (int j = 0; j < kF; ++j) {
    double largest = 0;
    for (int k = 0; k < kBasis; ++k) largest = std::max(largest, std::abs(estimate.gradient(w0 + k * kF + j)));
    EXPECT_GT(largest, 1e-6) << "torque " << j;
  }
}

// TP's forced weights reach the one-pass branch: k = 0 is RP, k = 1 is LR,
// bit for bit from the same random numbers; GTP at k = 1 is GLR.
TEST(TwoControls, ForcedTpWeightsReproduceRpAndLr) {
  auto tc = MakeTwoControlProblem(6);
  EstimatorOptions k0, k1;
  k0.forced_k_lr = 0.0;
  k1.forced_k_lr = 1.0;
  const GradientEstimate rp = RunMethod("RP", {}, tc->problem, 9, 1);
  const GradientEstimate tp0 = RunMethod("TP", k0, tc->problem, 9, 1);
  EXPECT_EQ(tp0.gradient, rp.gradient);
  EXPECT_EQ(tp0.per_particle, rp.per_particle);
  const GradientEstimate lr = RunMethod("LR", {}, tc->problem, 9, 1);
  const GradientEstimate tp1 = RunMethod("TP", k1, tc->problem, 9, 1);
  EXPECT_EQ(tp1.gradient, lr.gradient);
  EXPECT_EQ(tp1.per_particle, lr.per_particle);
  EXPECT_NE(lr.gradient, rp.gradient);
  // Sampled shaping derivatives: both draw the same samples from the same seed.
  EXPECT_EQ(RunMethod("GTP", k1, tc->problem, 9, 1).gradient,
            RunMethod("GLR", {}, tc->problem, 9, 1).gradient);
}

TEST(TwoControls, EveryMethodEstimatesFinitely) {
  auto tc = MakeTwoControlProblem(8);
  for (const std::string& method : ParticleMethodNames()) {
    const GradientEstimate e = RunMethod(method, {}, tc->problem, 12, 2);
    ASSERT_TRUE(e.finite) << method;
    ASSERT_EQ(e.per_particle.rows(), 12) << method;
    const Vector mean = e.per_particle.colwise().mean().transpose();
    EXPECT_LT((mean - e.gradient).cwiseAbs().maxCoeff(), 1e-12 * (1 + e.gradient.cwiseAbs().maxCoeff()))
        << method;
    EXPECT_GT(e.gradient.norm(), 0) << method;
    for (double k : e.k_lr) EXPECT_TRUE(k >= 0.0 && k <= 1.0) << method << " k " << k;
  }
  // Over 8 steps TP's adaptive weight is not stuck at one branch.
  const GradientEstimate tp = RunMethod("TP", {}, tc->problem, 20, 4);
  ASSERT_EQ(tp.k_lr.size(), 8u);
  EXPECT_LT(*std::min_element(tp.k_lr.begin(), tp.k_lr.end()),
            *std::max_element(tp.k_lr.begin(), tp.k_lr.end()));
}

// The oscillator of linear_gaussian.h with a second control that reaches no
// state (B's second column 0) and a zero gain: the same rollout as the
// one-control system, and the F > 1 combination (both branches' rows formed
// separately) must give the one-control pass's k_LR and gradient, the inert
// control's parameters a zero gradient.
TEST(TwoControls, AdaptiveTpWithAnInertControlIsTheOneControlPass) {
  auto one = testing::MakeOscillator(10);
  Matrix b2 = Matrix::Zero(2, 2);
  b2.col(0) = one->dynamics.b().col(0);
  const Vector& t1 = one->policy.theta();  // [k (2), k0]
  Vector t2(6);                            // [K row-major (2 x 2), k0 (2)]
  t2 << t1(0), t1(1), 0.0, 0.0, t1(2), 0.0;
  testing::LinearGaussian two(
      testing::LinearDynamics(one->dynamics.a(), b2, Vector::Zero(2), Vector::Constant(2, 0.01)),
      testing::LinearPolicy(t2, 2), one->cost, one->problem.mu0, one->problem.initial_std, 10);
  for (const std::string method : {"TP", "GTP"}) {
    SCOPED_TRACE(method);
    // Same seed, same draws: the rollouts and GTP's shaping samples have the
    // same shapes on both systems.
    const GradientEstimate a = RunMethod(method, {}, one->problem, 16, 5);
    const GradientEstimate b = RunMethod(method, {}, two.problem, 16, 5);
    ASSERT_TRUE(a.finite && b.finite);
    ASSERT_EQ(a.k_lr.size(), b.k_lr.size());
    bool mixed = false;
    for (size_t t = 0; t < a.k_lr.size(); ++t) {
      EXPECT_NEAR(b.k_lr[t], a.k_lr[t], 1e-9 * (1 + a.k_lr[t])) << "step " << t;
      mixed = mixed || (a.k_lr[t] > 0.01 && a.k_lr[t] < 0.99);
    }
    EXPECT_TRUE(mixed) << "the combination should weigh both branches somewhere";
    const double tol = 1e-9 * (1 + a.gradient.cwiseAbs().maxCoeff());
    EXPECT_NEAR(b.gradient(0), a.gradient(0), tol);
    EXPECT_NEAR(b.gradient(1), a.gradient(1), tol);
    EXPECT_NEAR(b.gradient(4), a.gradient(2), tol);
    EXPECT_EQ(b.gradient(2), 0.0);
    EXPECT_EQ(b.gradient(3), 0.0);
    EXPECT_EQ(b.gradient(5), 0.0);
    EXPECT_GT(a.gradient.norm(), 0.0);
  }
}

}  // namespace multi_control_test
}  // namespace totalgrad::estimators
