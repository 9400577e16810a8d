// Gaussian fits, the Cholesky backward pass and Gaussian resampling (GR):
// every reverse-mode map against central finite differences.
#include "core/estimators/gaussian_fit.h"

#include <cmath>

#include <Eigen/Cholesky>
#include <gtest/gtest.h>

#include "core/diff/gradient_checker.h"
#include "core/estimators/gaussian_resampling.h"
#include "core/estimators/synthetic_problem.h"
#include "core/estimators/total_propagation.h"

namespace totalgrad::estimators {
namespace gaussian_fit_test {

RowMatrix RandomRows(int p, int s, uint64_t seed) {
  Rng rng(seed, Stream::kStudy);
  RowMatrix x(p, s);
  rng.FillNormal(&x);
  return x;
}

Matrix RandomLower(int s, uint64_t seed) {
  RowMatrix w = RandomRows(s, s, seed);
  Matrix l = w;
  l.triangularView<Eigen::StrictlyUpper>().setZero();
  return l;
}

// Symmetric matrices as the vector of their lower triangle (row-major order).
Vector PackLower(const Matrix& a) {
  const int s = static_cast<int>(a.rows());
  Vector v(s * (s + 1) / 2);
  int k = 0;
  for (int r = 0; r < s; ++r)
    for (int c = 0; c <= r; ++c) v(k++) = a(r, c);
  return v;
}
Matrix UnpackSymmetric(const Vector& v, int s) {
  Matrix a(s, s);
  int k = 0;
  for (int r = 0; r < s; ++r)
    for (int c = 0; c <= r; ++c) a(r, c) = a(c, r) = v(k++);
  return a;
}
// d f / d(lower entry (r, c)) of a symmetric argument = A_bar(r,c) (+ A_bar(c,r) off the diagonal).
Vector PackSymmetricGradient(const Matrix& a_bar) {
  const int s = static_cast<int>(a_bar.rows());
  Vector v(s * (s + 1) / 2);
  int k = 0;
  for (int r = 0; r < s; ++r)
    for (int c = 0; c <= r; ++c) v(k++) = r == c ? a_bar(r, r) : a_bar(r, c) + a_bar(c, r);
  return v;
}

TEST(CholeskyBackward, MatchesFiniteDifferences) {
  const int s = 4;
  const RowMatrix b = RandomRows(s, s, 1);
  Matrix a = b.transpose() * b;
  a.diagonal().array() += 0.5;
  const Matrix w = RandomLower(s, 2);
  const Matrix l = a.llt().matrixL();
  const Matrix a_bar = CholeskyBackward(l, w);
  EXPECT_LT((a_bar - a_bar.transpose()).cwiseAbs().maxCoeff(), 1e-14) << "symmetric convention";
  const diff::VectorFunction f = [&](const Vector& packed, Vector* out) {
    const Matrix lp = UnpackSymmetric(packed, s).llt().matrixL();
    out->resize(1);
    (*out)(0) = lp.cwiseProduct(w).sum();
    return std::isfinite((*out)(0));
  };
  const diff::CheckResult r =
      diff::CheckJacobian(f, PackLower(a), PackSymmetricGradient(a_bar).transpose());
  EXPECT_TRUE(r.ok) << r.log;
}

TEST(CholeskyBackward, ReadsOnlyTheLowerTriangleOfTheCotangent) {
  const int s = 3;
  const RowMatrix b = RandomRows(s, s, 3);
  Matrix a = b.transpose() * b + Matrix::Identity(s, s);
  const Matrix l = a.llt().matrixL();
  Matrix w = RandomLower(s, 4);
  const Matrix expected = CholeskyBackward(l, w);
  w(0, 2) = 7.0;  // strictly upper: must be ignored
  EXPECT_EQ(CholeskyBackward(l, w), expected);
}

// f(x) = w^T mean(x) + <W, chol(cov(x) + jitter I)>, the composition GR and
// the sampled shaping derivatives differentiate.
TEST(GaussianFitBackward, MatchesFiniteDifferences) {
  const int p = 7, s = 3;
  const RowMatrix x0 = RandomRows(p, s, 5);
  Rng rng(6, Stream::kStudy);
  Vector w(s);
  rng.FillNormal(&w);
  const Matrix wl = RandomLower(s, 7);
  const double jitter = 1e-3;
  GaussianFit fit;
  FitGaussian(x0, jitter, &fit);
  ASSERT_EQ(fit.jitter, jitter);
  RowMatrix x_bar;
  GaussianFitBackward(fit, w, CholeskyBackward(fit.chol, wl), &x_bar);
  const diff::VectorFunction f = [&](const Vector& flat, Vector* out) {
    const RowMatrix x = Eigen::Map<const RowMatrix>(flat.data(), p, s);
    GaussianFit g;
    FitGaussian(x, jitter, &g);
    out->resize(1);
    (*out)(0) = w.dot(g.mean) + g.chol.cwiseProduct(wl).sum();
    return std::isfinite((*out)(0));
  };
  const Vector flat = Eigen::Map<const Vector>(x0.data(), p * s);
  const Vector analytic = Eigen::Map<const Vector>(x_bar.data(), p * s);
  const diff::CheckResult r = diff::CheckJacobian(f, flat, analytic.transpose());
  EXPECT_TRUE(r.ok) << r.log;
}

TEST(FitGaussian, MomentsAndFactor) {
  const RowMatrix x = RandomRows(50, 3, 8);
  GaussianFit fit;
  FitGaussian(x, 0.0, &fit);
  EXPECT_EQ(fit.jitter, 0.0);
  const Vector mean = x.colwise().mean().transpose();
  const RowMatrix d = x.rowwise() - mean.transpose();
  const Matrix cov = d.transpose() * d / 49.0;
  EXPECT_LT((fit.mean - mean).norm(), 1e-14);
  EXPECT_LT((fit.covariance - cov).norm(), 1e-13);
  EXPECT_LT((fit.chol * fit.chol.transpose() - cov).norm(), 1e-13);
}

// P <= S makes the sample covariance singular: the fit adds the smallest
// jitter that factorises, and stays finite down to P = 1.
TEST(FitGaussian, JitterForSingularCovariance) {
  for (int p : {1, 2, 4}) {
    const RowMatrix x = RandomRows(p, 4, 9 + p);
    GaussianFit fit;
    FitGaussian(x, 0.0, &fit);
    EXPECT_GT(fit.jitter, 0.0) << p;
    EXPECT_TRUE(fit.chol.allFinite()) << p;
    Matrix a = fit.covariance;
    a.diagonal().array() += fit.jitter;
    EXPECT_LT((fit.chol * fit.chol.transpose() - a).norm(), 1e-12 * (1.0 + a.norm())) << p;
  }
}

// The resampler's backward map against finite differences of
// f(x') = sum_j <V_j, mean(x') + L(x') zeta_j> with zeta fixed.
TEST(GaussianResampler, BackwardMatchesFiniteDifferences) {
  const int p = 9, s = 4;
  StepRecord step;
  step.next_state = RandomRows(p, s, 20);
  const RowMatrix v = RandomRows(p, s, 21);
  GaussianResampler resampler;
  Rng rng(22, Stream::kResampling);
  resampler.Resample(&rng, &step);
  ASSERT_EQ(step.resample_fit.jitter, 0.0);
  RowMatrix gamma_pre;
  resampler.Backward(step, v, &gamma_pre);
  const RowMatrix zeta = step.resample_noise;
  const diff::VectorFunction f = [&](const Vector& flat, Vector* out) {
    StepRecord st;
    st.next_state = Eigen::Map<const RowMatrix>(flat.data(), p, s);
    GaussianFit g;
    FitGaussian(st.next_state, 0.0, &g);
    RowMatrix x = zeta * g.chol.transpose();
    x.rowwise() += g.mean.transpose();
    out->resize(1);
    (*out)(0) = x.cwiseProduct(v).sum();
    return true;
  };
  const RowMatrix pre = step.pre_resample_state;
  const Vector flat = Eigen::Map<const Vector>(pre.data(), p * s);
  const Vector analytic = Eigen::Map<const Vector>(gamma_pre.data(), p * s);
  const diff::CheckResult r = diff::CheckJacobian(f, flat, analytic.transpose());
  EXPECT_TRUE(r.ok) << r.log;
}

// GR end to end: with eps and zeta fixed the GR estimate is the exact
// derivative of the resampled objective, so finite differences check the
// whole composed backward pass (resampling + RP through the GP and policy).
TEST(GrEstimator, MatchesFiniteDifferencesWithFixedNoise) {
  SyntheticProblemOptions o;
  o.data = 40;
  o.horizon = 6;
  o.basis_functions = 10;
  o.seed = 3;
  auto sp = MakeSyntheticProblem(o);
  ASSERT_TRUE(sp.ok()) << sp.status();
  const Problem& problem = (*sp)->problem;
  const int particles = 8;
  auto estimator = MakeEstimator(Method::kGr, {});
  ASSERT_TRUE(estimator.ok());
  Rng rng(11, Stream::kParticleNoise);
  EstimateOptions eo;
  eo.particles = particles;
  eo.keep_per_particle = true;
  GradientEstimate estimate;
  ASSERT_TRUE((*estimator)->Estimate(problem, eo, &rng, &estimate).ok());
  ASSERT_TRUE(estimate.finite);
  EXPECT_GT(estimate.gradient.norm(), 1e-6);
  EXPECT_LT((estimate.per_particle.colwise().mean().transpose() - estimate.gradient).cwiseAbs().maxCoeff(),
            1e-12);

  GaussianResampler resampler;
  const diff::VectorFunction f = [&](const Vector& theta, Vector* out) {
    policy::RbfPolicy policy = *(*sp)->policy;
    policy.set_parameters(theta);
    const RbfParticlePolicy adapter(&policy);
    Problem pr = problem;
    pr.policy = &adapter;
    Rng r(11, Stream::kParticleNoise);
    Rollout rollout;
    RolloutRecording rec;
    rec.resampler = &resampler;
    if (!SimulateParticles(pr, particles, rec, &r, &rollout).ok()) return false;
    out->resize(1);
    (*out)(0) = rollout.objective;
    return std::isfinite((*out)(0));
  };
  diff::CheckOptions options;
  options.relative_tolerance = 1e-5;
  options.absolute_tolerance = 1e-8;
  const diff::CheckResult r =
      diff::CheckJacobian(f, (*sp)->policy->parameters(), estimate.gradient.transpose(), options);
  EXPECT_TRUE(r.ok) << r.log;
}

}  // namespace gaussian_fit_test
}  // namespace totalgrad::estimators
