// Moments of every PILCO block against Monte Carlo with 10^6 samples of the
// block's Gaussian input, within 5 Monte Carlo standard errors.
//
// Each block is exact given a Gaussian input (PILCO's approximation lies only
// in treating each block's output as Gaussian when it feeds the next block),
// so each comparison is exact up to sampling error. The step test samples
// the joint Gaussian of (state, GP input) that the step forms, which checks
// the assembly of every cross-covariance.
#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <string>
#include <vector>

#include "core/gaussian/expected_cost.h"
#include "core/pilco/gp_moments.h"
#include "core/pilco/policy_moments.h"
#include "core/pilco/propagation.h"
#include "core/pilco/saturation.h"
#include "core/gaussian/trig.h"
#include "tests/core/pilco/pilco_test_util.h"

namespace totalgrad::pilco {
namespace monte_carlo_test {

using testing::GaussianSampler;
using testing::MomentAccumulator;
using testing::WithinMcError;

constexpr int kSamples = 1000000;
constexpr int kBatch = 100000;
constexpr double kSigmas = 5.0;

// Posterior mean (B x D) and latent variance (B x D) of a full GP at rows z.
void PosteriorAt(const GaussianInputGp& gp, const RowMatrix& z, RowMatrix* mean, RowMatrix* var) {
  const int b = static_cast<int>(z.rows()), d = gp.num_outputs();
  mean->resize(b, d);
  var->resize(b, d);
  for (int a = 0; a < d; ++a) {
    const Vector il = gp.inv_lengthscale_sq.row(a).transpose();
    const Matrix zs = z * il.cwiseSqrt().asDiagonal();
    const Matrix xs = gp.inputs * il.cwiseSqrt().asDiagonal();
    Matrix k = zs * xs.transpose();  // b x n
    k *= 2.0;
    k.colwise() -= zs.rowwise().squaredNorm();
    k.rowwise() -= xs.rowwise().squaredNorm().transpose();
    k = (gp.signal_var(a) * (0.5 * k.array().min(0.0)).exp()).matrix();
    mean->col(a) = k * gp.beta.col(a);
    if (!gp.variance_weights.empty()) {
      const Matrix kk = k * gp.variance_weights[a];
      var->col(a) = gp.signal_var(a) - kk.cwiseProduct(k).rowwise().sum().array();
    }
  }
}

TEST(MonteCarloTest, AugmentWithTrig) {
  std::mt19937_64 rng(11);
  const Vector m = Eigen::Vector4d(0.2, 2.8, -0.3, 0.5);
  const Matrix s = testing::RandomCovariance(4, 0.4, &rng);
  Vector ym;
  Matrix ys;
  gaussian::AugmentWithTrig(m, s, 1, &ym, &ys);
  const GaussianSampler sampler(m, s);
  MomentAccumulator acc(6);
  acc.SetShift(ym);
  for (int done = 0; done < kSamples; done += kBatch) {
    const RowMatrix x = sampler.Sample(kBatch, &rng);
    RowMatrix y(kBatch, 6);
    y.leftCols(4) = x;
    y.col(4) = x.col(1).array().sin();
    y.col(5) = x.col(1).array().cos();
    acc.AddBatch(y);
  }
  EXPECT_TRUE(WithinMcError(ym, acc.Mean(), acc.MeanStdError(), kSigmas));
  EXPECT_TRUE(WithinMcError(ys, acc.Cov(), acc.CovStdError(), kSigmas));
}

// Two and three angles: the pair blocks (product formulas) and Stein's
// cross-covariances against samples; angles with large, correlated spread.
TEST(MonteCarloTest, AugmentWithSeveralAngles) {
  std::mt19937_64 rng(21);
  for (const std::vector<int>& angles : {std::vector<int>{4, 5}, std::vector<int>{0, 2, 5}}) {
    const int d = 6, ny = d + 2 * static_cast<int>(angles.size());
    Vector m(d);
    m << 0.3, -0.2, 0.5, 0.1, 2.9, 3.4;
    const Matrix s = testing::RandomCovariance(d, 0.5, &rng);
    Vector ym;
    Matrix ys;
    gaussian::AugmentWithTrig(m, s, angles, &ym, &ys);
    const GaussianSampler sampler(m, s);
    MomentAccumulator acc(ny);
    acc.SetShift(ym);
    for (int done = 0; done < kSamples; done += kBatch) {
      const RowMatrix x = sampler.Sample(kBatch, &rng);
      RowMatrix y(kBatch, ny);
      y.leftCols(d) = x;
      for (size_t k = 0; k < angles.size(); ++k) {
        y.col(d + 2 * k) = x.col(angles[k]).array().sin();
        y.col(d + 2 * k + 1) = x.col(angles[k]).array().cos();
      }
      acc.AddBatch(y);
    }
    EXPECT_TRUE(WithinMcError(ym, acc.Mean(), acc.MeanStdError(), kSigmas)) << angles.size();
    EXPECT_TRUE(WithinMcError(ys, acc.Cov(), acc.CovStdError(), kSigmas)) << angles.size();
    // The pair blocks are not negligible here (a zero block would fail).
    EXPECT_GT(std::abs(ys(d, d + 2)) + std::abs(ys(d + 1, d + 3)), 0.01);
  }
}

TEST(MonteCarloTest, GSat) {
  std::mt19937_64 rng(12);
  for (const auto& [mean, var] : {std::pair{0.4, 0.3}, {-1.2, 1.5}, {2.0, 0.01}}) {
    const SatMoments sm = GSat(mean, var, 10.0);
    const GaussianSampler sampler(Vector::Constant(1, mean), Matrix::Constant(1, 1, var));
    MomentAccumulator acc(2);
    acc.SetShift(Eigen::Vector2d(mean, sm.mean));
    for (int done = 0; done < kSamples; done += kBatch) {
      const RowMatrix a = sampler.Sample(kBatch, &rng);
      RowMatrix au(kBatch, 2);
      au.col(0) = a.col(0);
      au.col(1) = 10.0 * (9.0 * a.col(0).array().sin() + (3.0 * a.col(0).array()).sin()) / 8.0;
      acc.AddBatch(au);
    }
    EXPECT_TRUE(WithinMcError(Vector::Constant(1, sm.mean), acc.Mean().tail(1),
                              acc.MeanStdError().tail(1), kSigmas));
    EXPECT_TRUE(WithinMcError(Matrix::Constant(1, 1, sm.var), acc.Cov().bottomRightCorner(1, 1),
                              acc.CovStdError().bottomRightCorner(1, 1), kSigmas));
    // Cov(a, u) = var * c.
    EXPECT_TRUE(WithinMcError(Matrix::Constant(1, 1, var * sm.c), acc.Cov().block(0, 1, 1, 1),
                              acc.CovStdError().block(0, 1, 1, 1), kSigmas));
  }
}

// Two controls at once: E[u], Cov[u] (the outputs' covariance included) and
// Cov(a, u) = cov diag(c) against samples of correlated a.
TEST(MonteCarloTest, GSatJointTwoControls) {
  std::mt19937_64 rng(22);
  Vector mean(2);
  mean << 0.4, -1.1;
  Matrix cov(2, 2);
  cov << 0.6, 0.35, 0.35, 0.9;
  const Vector max_u = Eigen::Vector2d(2.0, 3.5);
  JointSatMoments j;
  GSatJoint(mean, cov, max_u, &j);
  const GaussianSampler sampler(mean, cov);
  MomentAccumulator acc(4);
  Vector shift(4);
  shift << mean, j.mean;
  acc.SetShift(shift);
  for (int done = 0; done < kSamples; done += kBatch) {
    const RowMatrix a = sampler.Sample(kBatch, &rng);
    RowMatrix au(kBatch, 4);
    au.leftCols(2) = a;
    for (int k = 0; k < 2; ++k)
      au.col(2 + k) = max_u(k) * (9.0 * a.col(k).array().sin() + (3.0 * a.col(k).array()).sin()) / 8.0;
    acc.AddBatch(au);
  }
  EXPECT_TRUE(WithinMcError(j.mean, acc.Mean().tail(2), acc.MeanStdError().tail(2), kSigmas));
  EXPECT_TRUE(WithinMcError(j.cov, acc.Cov().bottomRightCorner(2, 2),
                            acc.CovStdError().bottomRightCorner(2, 2), kSigmas));
  EXPECT_TRUE(WithinMcError(cov * j.c.asDiagonal(), acc.Cov().topRightCorner(2, 2),
                            acc.CovStdError().topRightCorner(2, 2), kSigmas));
  EXPECT_GT(std::abs(j.cov(0, 1)), 20 * acc.CovStdError()(2, 3)) << "a zero covariance would fail";
}

TEST(MonteCarloTest, RbfPolicyMeanFunction) {
  std::mt19937_64 rng(13);
  RbfPolicyShape shape;
  shape.num_basis = 10;
  shape.input_dim = 5;
  shape.jitter = 1e-6;
  const int c = 10, e = 5;
  Vector params(shape.num_parameters());
  params.head(c * e) = testing::RandomVector(c * e, 0.5, &rng);
  params.segment(c * e, e) = Eigen::VectorXd::LinSpaced(e, std::log(0.7), std::log(1.2));
  params.tail(c) = testing::RandomVector(c, 1.0, &rng);
  const Vector m = testing::RandomVector(e, 0.3, &rng);
  const Matrix s = testing::RandomCovariance(e, 0.15, &rng);
  PolicyMoments pm;
  ASSERT_TRUE(PolicyAtGaussian(shape, params, m, s, &pm).ok());
  const Eigen::Map<const RowMatrix> centres(params.data(), c, e);
  const Vector il2 = (-2.0 * params.segment(c * e, e).array()).exp().matrix();
  const Vector w = params.tail(c);
  const GaussianSampler sampler(m, s);
  MomentAccumulator acc(e + 1);
  Vector shift(e + 1);
  shift << m, pm.a_mean;
  acc.SetShift(shift);
  for (int done = 0; done < kSamples; done += kBatch) {
    const RowMatrix x = sampler.Sample(kBatch, &rng);
    Vector a = Vector::Zero(kBatch);
    for (int k = 0; k < c; ++k) {
      const RowMatrix diff = x.rowwise() - centres.row(k);
      a += w(k) * (-0.5 * (diff.array().square().matrix() * il2).array()).exp().matrix();
    }
    RowMatrix xa(kBatch, e + 1);
    xa.leftCols(e) = x;
    xa.col(e) = a;
    acc.AddBatch(xa);
  }
  EXPECT_TRUE(WithinMcError(Vector::Constant(1, pm.a_mean), acc.Mean().tail(1),
                            acc.MeanStdError().tail(1), kSigmas));
  EXPECT_TRUE(WithinMcError(Matrix::Constant(1, 1, pm.a_var - shape.jitter),
                            acc.Cov().bottomRightCorner(1, 1),
                            acc.CovStdError().bottomRightCorner(1, 1), kSigmas));
  // Cov(x, a) = s * a_cross.
  EXPECT_TRUE(WithinMcError(s * pm.a_cross, acc.Cov().col(e).head(e),
                            acc.CovStdError().col(e).head(e), kSigmas));
}

// Two controls: the unsquashed outputs' mean, covariance (the two outputs'
// covariance included) and Cov(x, a) = s a_cross against samples of x. (This
// block is exact given a Gaussian x; the saturation after it treats a as
// Gaussian, PILCO's approximation, and is checked given a Gaussian a in
// GSatJointTwoControls.)
TEST(MonteCarloTest, RbfPolicyTwoControls) {
  std::mt19937_64 rng(23);
  RbfPolicyShape shape;
  shape.num_basis = 8;
  shape.input_dim = 4;
  shape.jitter = 1e-6;
  shape.max_controls = Eigen::Vector2d(2.0, 3.5);
  const int c = 8, e = 4, f = 2;
  Vector params(shape.num_parameters());
  params.head(c * e) = testing::RandomVector(c * e, 0.5, &rng);
  params.segment(c * e, e) = Eigen::VectorXd::LinSpaced(e, std::log(0.7), std::log(1.2));
  params.tail(c * f) = testing::RandomVector(c * f, 1.0, &rng);
  const Vector m = testing::RandomVector(e, 0.3, &rng);
  const Matrix s = testing::RandomCovariance(e, 0.15, &rng);
  MultiPolicyMoments pm;
  ASSERT_TRUE(MultiPolicyAtGaussian(shape, params, m, s, &pm).ok());
  const Eigen::Map<const RowMatrix> centres(params.data(), c, e);
  const Vector il2 = (-2.0 * params.segment(c * e, e).array()).exp().matrix();
  const Eigen::Map<const RowMatrix> w(params.data() + c * e + e, c, f);
  const GaussianSampler sampler(m, s);
  MomentAccumulator acc(e + f);
  Vector shift(e + f);
  shift << m, pm.a_mean;
  acc.SetShift(shift);
  for (int done = 0; done < kSamples; done += kBatch) {
    const RowMatrix x = sampler.Sample(kBatch, &rng);
    RowMatrix a = RowMatrix::Zero(kBatch, f);
    for (int k = 0; k < c; ++k) {
      const RowMatrix diff = x.rowwise() - centres.row(k);
      const Vector phi = (-0.5 * (diff.array().square().matrix() * il2).array()).exp().matrix();
      for (int j = 0; j < f; ++j) a.col(j) += w(k, j) * phi;
    }
    RowMatrix xa(kBatch, e + f);
    xa.leftCols(e) = x;
    xa.rightCols(f) = a;
    acc.AddBatch(xa);
  }
  EXPECT_TRUE(WithinMcError(pm.a_mean, acc.Mean().tail(f), acc.MeanStdError().tail(f), kSigmas));
  // a_cov carries gp2's jitter on its diagonal (PILCO's), the samples none.
  const Matrix a_cov = pm.a_cov - shape.jitter * Matrix::Identity(f, f);
  EXPECT_TRUE(WithinMcError(a_cov, acc.Cov().bottomRightCorner(f, f),
                            acc.CovStdError().bottomRightCorner(f, f), kSigmas));
  // Beyond 2 x the 5-SE band: a zero covariance would fail the check above.
  EXPECT_GT(std::abs(a_cov(0, 1)), 10 * acc.CovStdError()(e, e + 1));
  EXPECT_TRUE(WithinMcError(s * pm.a_cross, acc.Cov().topRightCorner(e, f),
                            acc.CovStdError().topRightCorner(e, f), kSigmas));
}

// gp0: mean, covariance (with model uncertainty) and input-output covariance.
TEST(MonteCarloTest, DynamicsGpWithModelUncertainty) {
  std::mt19937_64 rng(14);
  const int n = 30, e = 6, d = 4;
  const GaussianInputGp gp = testing::MakeTestGp(n, e, d, &rng);
  const Vector m = testing::RandomVector(e, 0.4, &rng);
  const Matrix s = testing::RandomCovariance(e, 0.25, &rng);
  GaussianPrediction pred;
  ASSERT_TRUE(PredictGaussian(gp, m, s, GaussianPredictionOptions(), &pred).ok());
  const GaussianSampler sampler(m, s);
  // Accumulate [x (E), m(x) (D), v(x) (D)].
  MomentAccumulator acc(e + 2 * d);
  Vector shift = Vector::Zero(e + 2 * d);
  shift << m, pred.mean, Vector::Zero(d);
  acc.SetShift(shift);
  for (int done = 0; done < kSamples; done += kBatch) {
    const RowMatrix x = sampler.Sample(kBatch, &rng);
    RowMatrix mean, var;
    PosteriorAt(gp, x, &mean, &var);
    RowMatrix row(kBatch, e + 2 * d);
    row << x, mean, var;
    acc.AddBatch(row);
  }
  const Vector mc_mean = acc.Mean();
  const Matrix mc_cov = acc.Cov();
  const Matrix mc_cov_se = acc.CovStdError();
  const Vector mc_mean_se = acc.MeanStdError();
  EXPECT_TRUE(WithinMcError(pred.mean, mc_mean.segment(e, d), mc_mean_se.segment(e, d), kSigmas));
  // Cov[f] = Cov(m(x)) + diag(E[v(x)]).
  Matrix expected_cov = mc_cov.block(e, e, d, d);
  Matrix se = mc_cov_se.block(e, e, d, d);
  expected_cov.diagonal() += mc_mean.tail(d);
  se.diagonal() += mc_mean_se.tail(d);
  EXPECT_TRUE(WithinMcError(pred.cov, expected_cov, se, kSigmas));
  EXPECT_TRUE(WithinMcError(s * pred.cross, mc_cov.block(0, e, e, d), mc_cov_se.block(0, e, e, d),
                            kSigmas));
  // The model-uncertainty term is not negligible here (so the test means something).
  EXPECT_GT(mc_mean.tail(d).minCoeff(), 1e-3);
}

TEST(MonteCarloTest, AngleCost) {
  std::mt19937_64 rng(15);
  const Vector target = Eigen::Vector4d(0, M_PI, 0, 0);
  const Matrix q = Eigen::Vector4d(1, 1, 0, 0).asDiagonal();
  auto cost = gaussian::GaussianCost::Angle(target, q);
  ASSERT_TRUE(cost.ok());
  const Vector m = Eigen::Vector4d(0.3, 2.5, 0.1, 0.2);
  const Matrix s = testing::RandomCovariance(4, 0.3, &rng);
  gaussian::CostMoments cm;
  ASSERT_TRUE(cost->Evaluate(m, s, false, &cm).ok());
  const GaussianSampler sampler(m, s);
  MomentAccumulator acc(1);
  acc.SetShift(Vector::Constant(1, cm.mean));
  for (int done = 0; done < kSamples; done += kBatch) {
    const RowMatrix x = sampler.Sample(kBatch, &rng);
    const Vector c = 1.0 - (-(x.col(0).array().square() +
                              (x.col(1).array() - M_PI).square())).exp();
    acc.AddBatch(c);
  }
  EXPECT_TRUE(WithinMcError(Vector::Constant(1, cm.mean), acc.Mean(), acc.MeanStdError(), kSigmas));
  EXPECT_TRUE(WithinMcError(Matrix::Constant(1, 1, cm.var), acc.Cov(), acc.CovStdError(), kSigmas));
}

// loss_cp evaluates the tip cost on the Gaussian approximation of
// y = [x; sin; cos]: exact for y ~ N(AugmentWithTrig(m, S)).
TEST(MonteCarloTest, TipCostOnTheAugmentedGaussian) {
  std::mt19937_64 rng(16);
  auto cost = gaussian::GaussianCost::Tip(4, 0, 1, 0.5, 0.25);
  ASSERT_TRUE(cost.ok());
  const Vector m = Eigen::Vector4d(0.1, 2.7, 0.1, 0.2);
  const Matrix s = testing::RandomCovariance(4, 0.05, &rng);
  gaussian::CostMoments cm;
  ASSERT_TRUE(cost->Evaluate(m, s, false, &cm).ok());
  Vector ym;
  Matrix ys;
  gaussian::AugmentWithTrig(m, s, 1, &ym, &ys);
  const GaussianSampler sampler(ym, ys);
  MomentAccumulator acc(1);
  acc.SetShift(Vector::Constant(1, cm.mean));
  const double l = 0.5, w = 0.25;
  for (int done = 0; done < kSamples; done += kBatch) {
    const RowMatrix y = sampler.Sample(kBatch, &rng);
    const Eigen::ArrayXd d2 = (y.col(0).array() + l * y.col(4).array()).square() +
                              l * l * (y.col(5).array() + 1.0).square();
    const Vector c = (1.0 - (-d2 / (2 * w * w)).exp()).matrix();
    acc.AddBatch(c);
  }
  EXPECT_TRUE(WithinMcError(Vector::Constant(1, cm.mean), acc.Mean(), acc.MeanStdError(), kSigmas));
  EXPECT_TRUE(WithinMcError(Matrix::Constant(1, 1, cm.var), acc.Cov(), acc.CovStdError(), kSigmas));
}

// lossSat with several angles (2, as the cart-double-pendulum) and a
// general Q on z: exact for z ~ N(AugmentWithTrig(m, S, angles)), its
// Gaussian approximation. Each width's mean and variance against Monte
// Carlo; the several-width cost is the mean of their means and (PILCO's
// S2 / n) the mean of their variances.
TEST(MonteCarloTest, SaturatingCostSeveralAnglesOnTheAugmentedGaussian) {
  std::mt19937_64 rng(18);
  const std::vector<int> angles = {1, 3};
  const int d = 4, nz = 8;
  const Matrix q = testing::RandomCovariance(nz, 0.3, &rng);
  const Vector m = Eigen::Vector4d(0.1, 2.7, -0.2, 0.4);
  const Matrix s = testing::RandomCovariance(d, 0.2, &rng);
  const std::vector<double> widths = {0.7, 1.6};
  Vector ym;
  Matrix ys;
  gaussian::AugmentWithTrig(m, s, angles, &ym, &ys);
  // A target near z's mean, so that neither width saturates the cost.
  const Vector target = ym + testing::RandomVector(nz, 0.3, &rng);
  const GaussianSampler sampler(ym, ys);
  double mean_of_means = 0, mean_of_vars = 0;
  for (double w : widths) {
    auto cost = gaussian::GaussianCost::Saturating(d, angles, q, target, {w});
    ASSERT_TRUE(cost.ok()) << cost.status();
    gaussian::CostMoments cm;
    ASSERT_TRUE(cost->Evaluate(m, s, false, &cm).ok());
    mean_of_means += cm.mean / widths.size();
    mean_of_vars += cm.var / widths.size();
    EXPECT_GT(cm.var, 1e-3);  // not a degenerate case
    MomentAccumulator acc(1);
    acc.SetShift(Vector::Constant(1, cm.mean));
    for (int done = 0; done < kSamples; done += kBatch) {
      const RowMatrix y = sampler.Sample(kBatch, &rng);
      const RowMatrix dz = y.rowwise() - target.transpose();
      const Vector quad = (dz * q).cwiseProduct(dz).rowwise().sum();
      const Vector c = (1.0 - (-0.5 * quad.array() / (w * w)).exp()).matrix();
      acc.AddBatch(c);
    }
    EXPECT_TRUE(WithinMcError(Vector::Constant(1, cm.mean), acc.Mean(), acc.MeanStdError(), kSigmas))
        << "width " << w;
    EXPECT_TRUE(WithinMcError(Matrix::Constant(1, 1, cm.var), acc.Cov(), acc.CovStdError(), kSigmas))
        << "width " << w;
  }
  auto both = gaussian::GaussianCost::Saturating(d, angles, q, target, widths);
  ASSERT_TRUE(both.ok());
  gaussian::CostMoments cm;
  ASSERT_TRUE(both->Evaluate(m, s, false, &cm).ok());
  EXPECT_NEAR(cm.mean, mean_of_means, 1e-15);
  EXPECT_NEAR(cm.var, mean_of_vars, 1e-15);
}

// The step's assembly: for (x, g) jointly Gaussian with the covariance the step
// forms, x' = x + f(g) has exactly the mean and covariance the step returns.
// One angle, and two (the step's (sin, cos) pair blocks in g's covariance).
// (angles, controls): one angle, two angles, two angles and two controls.
struct AssemblyCase {
  std::vector<int> angles;
  int controls;
};
class StepAssembly : public ::testing::TestWithParam<AssemblyCase> {};

TEST_P(StepAssembly, GivenTheJointGaussian) {
  std::mt19937_64 rng(17);
  const std::vector<int> angles = GetParam().angles;
  const int f = GetParam().controls;
  const int d = 4, ep = d + static_cast<int>(angles.size());
  const GaussianInputGp gp = testing::MakeTestGp(30, ep + f, d, &rng, 1.5);
  PropagationOptions options;
  options.angle_indices = angles;
  if (f > 1) options.max_controls = Vector::LinSpaced(f, 2.0, 3.5);
  options.num_basis = 6;
  const Propagator prop(&gp, options);
  Vector params(prop.num_parameters());
  params.head(6 * ep) = testing::RandomVector(6 * ep, 0.7, &rng);
  params.segment(6 * ep, ep).setConstant(std::log(0.9));
  params.tail(6 * f) = testing::RandomVector(6 * f, 0.5, &rng);
  const Vector m = Eigen::Vector4d(0.1, 0.4, -0.2, 0.3);
  const Matrix s = testing::RandomCovariance(d, 0.05, &rng);
  StepCache cache;
  Vector m_next;
  Matrix s_next;
  ASSERT_TRUE(prop.Step(params, m, s, &m_next, &s_next, &cache).ok());
  // Joint Gaussian of z = [x (D), g (Ep + F)].
  const int eg = ep + f;
  Matrix cxg(d, eg);
  cxg.leftCols(ep) = cache.s_xp;
  if (f == 1) {
    cxg.col(ep) = cache.s_xp * cache.policy.u_cross;
  } else {
    cxg.rightCols(f) = cache.s_xp * cache.multi.u_cross;
  }
  Vector zm(d + eg);
  zm << m, cache.g_mean;
  Matrix zs(d + eg, d + eg);
  zs << s, cxg, cxg.transpose(), cache.g_cov;
  const GaussianSampler sampler(zm, zs);
  MomentAccumulator acc(2 * d);
  Vector shift(2 * d);
  shift << m_next, Vector::Zero(d);
  acc.SetShift(shift);
  for (int done = 0; done < kSamples; done += kBatch) {
    const RowMatrix z = sampler.Sample(kBatch, &rng);
    RowMatrix mean, var;
    PosteriorAt(gp, z.rightCols(eg), &mean, &var);
    RowMatrix row(kBatch, 2 * d);
    row << z.leftCols(d) + mean, var;
    acc.AddBatch(row);
  }
  EXPECT_TRUE(WithinMcError(m_next, acc.Mean().head(d), acc.MeanStdError().head(d), kSigmas));
  Matrix expected = acc.Cov().topLeftCorner(d, d);
  Matrix se = acc.CovStdError().topLeftCorner(d, d);
  expected.diagonal() += acc.Mean().tail(d);
  se.diagonal() += acc.MeanStdError().tail(d);
  EXPECT_TRUE(WithinMcError(s_next, expected, se, kSigmas));
  // The cross-covariance terms Cov(x, Delta) are far above the MC error, so
  // leaving them out would fail this test.
  const Matrix cross_terms = s_next - s - cache.delta.cov;
  EXPECT_GT(cross_terms.cwiseAbs().maxCoeff(), 50.0 * se.maxCoeff());
}

INSTANTIATE_TEST_SUITE_P(Angles, StepAssembly,
                         ::testing::Values(AssemblyCase{{1}, 1}, AssemblyCase{{1, 3}, 1},
                                           AssemblyCase{{2, 3}, 2}),
                         [](const auto& info) {
                           return "Angles" + std::to_string(info.param.angles.size()) + "Controls" +
                                  std::to_string(info.param.controls);
                         });

// The same with the GP on its own index set into z (PILCO's dyni beside
// poli): g = [q; u], q = z(dynamics_inputs) including a raw angle the policy
// does not see, Cov(x, g) = [Cov(x, q), Cov(x, p) u_cross]. One and two
// controls, two angles.
class StepAssemblySeparate : public ::testing::TestWithParam<int> {};

TEST_P(StepAssemblySeparate, GivenTheJointGaussian) {
  std::mt19937_64 rng(19);
  const int f = GetParam();
  const int d = 4;
  const std::vector<int> poli = {0, 2, 4, 5, 6, 7}, dyni = {0, 2, 3, 4, 5, 6, 7};
  const int ep = 6, eq = 7;
  const GaussianInputGp gp = testing::MakeTestGp(30, eq + f, d, &rng, 1.5);
  PropagationOptions options;
  options.angle_indices = {1, 3};
  options.policy_inputs = poli;
  options.dynamics_inputs = dyni;
  if (f > 1) options.max_controls = Vector::LinSpaced(f, 2.0, 3.5);
  options.num_basis = 6;
  const Propagator prop(&gp, options);
  Vector params(prop.num_parameters());
  params.head(6 * ep) = testing::RandomVector(6 * ep, 0.7, &rng);
  params.segment(6 * ep, ep).setConstant(std::log(0.9));
  params.tail(6 * f) = testing::RandomVector(6 * f, 0.5, &rng);
  const Vector m = Eigen::Vector4d(0.1, 0.4, -0.2, 0.3);
  const Matrix s = testing::RandomCovariance(d, 0.05, &rng);
  StepCache cache;
  Vector m_next;
  Matrix s_next;
  ASSERT_TRUE(prop.Step(params, m, s, &m_next, &s_next, &cache).ok());
  ASSERT_EQ(cache.g_mean.size(), eq + f);
  const int eg = eq + f;
  Matrix cxg(d, eg);
  cxg.leftCols(eq) = cache.s_xq;
  cxg.rightCols(f) = cache.s_xp * cache.u_cross;
  Vector zm(d + eg);
  zm << m, cache.g_mean;
  Matrix zs(d + eg, d + eg);
  zs << s, cxg, cxg.transpose(), cache.g_cov;
  const GaussianSampler sampler(zm, zs);
  MomentAccumulator acc(2 * d);
  Vector shift(2 * d);
  shift << m_next, Vector::Zero(d);
  acc.SetShift(shift);
  for (int done = 0; done < kSamples; done += kBatch) {
    const RowMatrix z = sampler.Sample(kBatch, &rng);
    RowMatrix mean, var;
    PosteriorAt(gp, z.rightCols(eg), &mean, &var);
    RowMatrix row(kBatch, 2 * d);
    row << z.leftCols(d) + mean, var;
    acc.AddBatch(row);
  }
  EXPECT_TRUE(WithinMcError(m_next, acc.Mean().head(d), acc.MeanStdError().head(d), kSigmas));
  Matrix expected = acc.Cov().topLeftCorner(d, d);
  Matrix se = acc.CovStdError().topLeftCorner(d, d);
  expected.diagonal() += acc.Mean().tail(d);
  se.diagonal() += acc.MeanStdError().tail(d);
  EXPECT_TRUE(WithinMcError(s_next, expected, se, kSigmas));
  const Matrix cross_terms = s_next - s - cache.delta.cov;
  EXPECT_GT(cross_terms.cwiseAbs().maxCoeff(), 50.0 * se.maxCoeff());
}

INSTANTIATE_TEST_SUITE_P(Controls, StepAssemblySeparate, ::testing::Values(1, 2));

}  // namespace monte_carlo_test
}  // namespace totalgrad::pilco
