// Derivatives of every PILCO block against central finite differences, with
// respect to the block's own inputs (mean, covariance, parameters), and
// deliberately wrong derivatives that the check must reject.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>
#include <string>
#include <vector>

#include "core/diff/gradient_checker.h"
#include "core/gaussian/expected_cost.h"
#include "core/pilco/gp_moments.h"
#include "core/pilco/policy_moments.h"
#include "core/pilco/propagation.h"
#include "core/pilco/saturation.h"
#include "core/gaussian/trig.h"
#include "tests/core/pilco/pilco_test_util.h"

namespace totalgrad::pilco {
namespace blocks_test {

using testing::BlockBackward;
using testing::BlockForward;
using testing::CheckBlock;
using testing::Flatten;

diff::CheckOptions Tight() {
  diff::CheckOptions o;
  o.relative_step = 1e-6;
  o.relative_tolerance = 1e-6;
  o.absolute_tolerance = 1e-8;
  return o;
}

// ---------------------------------------------------------------- gTrig, gSat

TEST(GTrigTest, JacobianMatchesFiniteDifferences) {
  for (const auto& [mean, var] : {std::pair{0.3, 0.2}, {2.9, 1e-4}, {-1.2, 3.0}, {3.14159, 0.0}}) {
    const diff::VectorFunction f = [](const Vector& x, Vector* y) {
      *y = gaussian::GTrig(x(0), x(1)).AsVector();
      return true;
    };
    const Vector x = Eigen::Vector2d(mean, var);
    const diff::CheckResult r = diff::CheckJacobian(f, x, gaussian::Dx_GTrig(mean, var), Tight());
    EXPECT_TRUE(r.ok) << "mean " << mean << " var " << var << ": " << r.log;
  }
}

TEST(GSatTest, JacobianMatchesFiniteDifferences) {
  for (const auto& [mean, var] : {std::pair{0.3, 0.2}, {1.5, 1e-5}, {-2.2, 2.0}, {0.0, 0.0}}) {
    const diff::VectorFunction f = [](const Vector& x, Vector* y) {
      *y = GSat(x(0), x(1), 10.0).AsVector();
      return true;
    };
    const Vector x = Eigen::Vector2d(mean, var);
    const diff::CheckResult r = diff::CheckJacobian(f, x, Dx_GSat(mean, var, 10.0), Tight());
    EXPECT_TRUE(r.ok) << "mean " << mean << " var " << var << ": " << r.log;
  }
}

TEST(GSatTest, WrongJacobianIsRejected) {
  const diff::VectorFunction f = [](const Vector& x, Vector* y) {
    *y = GSat(x(0), x(1), 10.0).AsVector();
    return true;
  };
  Eigen::Matrix<double, 3, 2> wrong = Dx_GSat(0.4, 0.3, 10.0);
  wrong(1, 1) *= 1.001;  // 0.1 % error in dVar/dvar
  EXPECT_FALSE(diff::CheckJacobian(f, Eigen::Vector2d(0.4, 0.3), wrong, Tight()).ok);
}

TEST(GSatTest, DeterministicInputIsTheSquash) {
  for (double a : {-1.3, 0.0, 0.4, 1.5707963}) {
    const SatMoments s = GSat(a, 0.0, 10.0);
    EXPECT_NEAR(s.mean, 10.0 * (9 * std::sin(a) + std::sin(3 * a)) / 8, 1e-14);
    EXPECT_NEAR(s.var, 0.0, 1e-13);
    EXPECT_NEAR(s.c, 10.0 * (9 * std::cos(a) + 3 * std::cos(3 * a)) / 8, 1e-13);
  }
}

// F controls saturated at once: [E u; Cov u; c] against finite differences
// of (mean, cov) for F = 2 and 3, correlated; F = 1 equals GSat.
TEST(GSatJointTest, ReverseModeMatchesFiniteDifferences) {
  std::mt19937_64 rng(4);
  for (int f : {2, 3}) {
    const Vector m = testing::RandomVector(f, 1.0, &rng);
    const Matrix s = testing::RandomCovariance(f, 0.5, &rng);
    const Vector max_u = Vector::LinSpaced(f, 2.0, 3.5);
    const BlockForward fwd = [&](const Vector& mm, const Matrix& ss, const Vector&, Vector* y) {
      JointSatMoments j;
      GSatJoint(mm, ss, max_u, &j);
      y->resize(f + f * f + f);
      *y << j.mean, Flatten(j.cov), j.c;
      return true;
    };
    const BlockBackward bwd = [&](const Vector& mm, const Matrix& ss, const Vector&,
                                  const Vector& yb, Vector* mb, Matrix* sb, Vector*) {
      *mb = Vector::Zero(f);
      *sb = Matrix::Zero(f, f);
      const Matrix cov_bar = Eigen::Map<const Matrix>(yb.data() + f, f, f);
      GSatJointBackward(mm, ss, max_u, yb.head(f), cov_bar, yb.tail(f), mb, sb);
      return true;
    };
    const diff::CheckResult r = CheckBlock(fwd, bwd, m, s, Vector(), Tight());
    EXPECT_TRUE(r.ok) << "F " << f << ": " << r.log;
    JointSatMoments j;
    GSatJoint(m, s, max_u, &j);
    EXPECT_GT(std::abs(j.cov(0, 1)), 1e-3) << "the outputs' covariance should matter";
  }
  // One control: GSat's numbers (another formula; equal to round-off).
  for (const auto& [mean, var] : {std::pair{0.3, 0.2}, {-2.2, 2.0}, {1.0, 0.0}}) {
    JointSatMoments j;
    GSatJoint(Vector::Constant(1, mean), Matrix::Constant(1, 1, var), Vector::Constant(1, 10.0), &j);
    const SatMoments g = GSat(mean, var, 10.0);
    EXPECT_NEAR(j.mean(0), g.mean, 1e-12);
    EXPECT_NEAR(j.cov(0, 0), g.var, 1e-12);
    EXPECT_NEAR(j.c(0), g.c, 1e-12);
  }
}

// ---------------------------------------------------------------- augmentation

TEST(AugmentWithTrigTest, ReverseModeMatchesFiniteDifferences) {
  std::mt19937_64 rng(1);
  const int d = 4, angle = 1;
  const Vector m = testing::RandomVector(d, 1.0, &rng);
  const Matrix s = testing::RandomCovariance(d, 0.3, &rng);
  const BlockForward fwd = [&](const Vector& mm, const Matrix& ss, const Vector&, Vector* y) {
    Vector ym;
    Matrix ys;
    gaussian::AugmentWithTrig(mm, ss, angle, &ym, &ys);
    y->resize(ym.size() + ys.size());
    *y << ym, Flatten(ys);
    return true;
  };
  const BlockBackward bwd = [&](const Vector& mm, const Matrix& ss, const Vector&,
                                const Vector& yb, Vector* mb, Matrix* sb, Vector*) {
    const int ny = d + 2;
    const Vector ymb = yb.head(ny);
    const Matrix ysb = Eigen::Map<const Matrix>(yb.data() + ny, ny, ny);
    *mb = Vector::Zero(d);
    *sb = Matrix::Zero(d, d);
    gaussian::AugmentWithTrigBackward(mm, ss, angle, ymb, ysb, mb, sb);
    return true;
  };
  const diff::CheckResult r = CheckBlock(fwd, bwd, m, s, Vector(), Tight());
  EXPECT_TRUE(r.ok) << r.log;
}

// Several angles (the cart-double-pendulum's two, and three for the
// generic pair loop): y = [x; sin, cos per angle].
struct AnglesCase {
  int d;
  std::vector<int> angles;
};
class AugmentWithTrigAngles : public ::testing::TestWithParam<AnglesCase> {};

TEST_P(AugmentWithTrigAngles, ReverseModeMatchesFiniteDifferences) {
  const int d = GetParam().d;
  const std::vector<int> angles = GetParam().angles;
  const int ny = d + 2 * static_cast<int>(angles.size());
  std::mt19937_64 rng(2);
  const Vector m = testing::RandomVector(d, 1.5, &rng);
  // Correlated angles, so that the pair blocks carry weight.
  const Matrix s = testing::RandomCovariance(d, 0.3, &rng);
  const BlockForward fwd = [&](const Vector& mm, const Matrix& ss, const Vector&, Vector* y) {
    Vector ym;
    Matrix ys;
    gaussian::AugmentWithTrig(mm, ss, angles, &ym, &ys);
    y->resize(ym.size() + ys.size());
    *y << ym, Flatten(ys);
    return true;
  };
  const BlockBackward bwd = [&](const Vector& mm, const Matrix& ss, const Vector&,
                                const Vector& yb, Vector* mb, Matrix* sb, Vector*) {
    const Vector ymb = yb.head(ny);
    const Matrix ysb = Eigen::Map<const Matrix>(yb.data() + ny, ny, ny);
    *mb = Vector::Zero(d);
    *sb = Matrix::Zero(d, d);
    gaussian::AugmentWithTrigBackward(mm, ss, angles, ymb, ysb, mb, sb);
    return true;
  };
  const diff::CheckResult r = CheckBlock(fwd, bwd, m, s, Vector(), Tight());
  EXPECT_TRUE(r.ok) << r.log;

  // A reverse mode that treats the angles as independent (each angle's
  // one-angle backward on its own block, the pair blocks' dependence on
  // (m, S) dropped) must be rejected.
  const BlockBackward independent = [&](const Vector& mm, const Matrix& ss, const Vector&,
                                        const Vector& yb, Vector* mb, Matrix* sb, Vector*) {
    *mb = Vector::Zero(d);
    *sb = Matrix::Zero(d, d);
    const Matrix ysb = Eigen::Map<const Matrix>(yb.data() + ny, ny, ny);
    for (size_t k = 0; k < angles.size(); ++k) {
      std::vector<int> idx(d);
      for (int i = 0; i < d; ++i) idx[i] = i;
      idx.push_back(d + 2 * static_cast<int>(k));
      idx.push_back(d + 2 * static_cast<int>(k) + 1);
      Vector ymb(d + 2);
      Matrix ysb1(d + 2, d + 2);
      for (int i = 0; i < d + 2; ++i) {
        ymb(i) = i < d ? (k == 0 ? yb(i) : 0.0) : yb(idx[i]);
        for (int j = 0; j < d + 2; ++j)
          ysb1(i, j) = (i < d && j < d && k > 0) ? 0.0 : ysb(idx[i], idx[j]);
      }
      gaussian::AugmentWithTrigBackward(mm, ss, angles[k], ymb, ysb1, mb, sb);
    }
    return true;
  };
  EXPECT_FALSE(CheckBlock(fwd, independent, m, s, Vector(), Tight()).ok);
}

INSTANTIATE_TEST_SUITE_P(Angles, AugmentWithTrigAngles,
                         ::testing::Values(AnglesCase{6, {4, 5}}, AnglesCase{4, {0, 2}},
                                           AnglesCase{5, {0, 2, 4}}),
                         [](const auto& info) {
                           std::string name = "D" + std::to_string(info.param.d) + "Angles";
                           for (int a : info.param.angles) name += std::to_string(a);
                           return name;
                         });

// One angle given as a list is the one-angle function, bit for bit (the
// scenes with one angle keep their numbers).
TEST(AugmentWithTrigTest, OneAngleListIsTheOneAngleFunction) {
  std::mt19937_64 rng(3);
  const Vector m = testing::RandomVector(4, 1.0, &rng);
  const Matrix s = testing::RandomCovariance(4, 0.3, &rng);
  Vector y1, y2;
  Matrix c1, c2;
  gaussian::AugmentWithTrig(m, s, 1, &y1, &c1);
  gaussian::AugmentWithTrig(m, s, std::vector<int>{1}, &y2, &c2);
  EXPECT_EQ(y1, y2);
  EXPECT_EQ(c1, c2);
}

// ---------------------------------------------------------------- GP blocks

TEST(GpMomentsTest, Gp0ReverseModeMatchesFiniteDifferences) {
  std::mt19937_64 rng(2);
  const int n = 30, e = 6, d = 4;
  const GaussianInputGp gp = testing::MakeTestGp(n, e, d, &rng);
  for (const bool noise : {false, true}) {
    GaussianPredictionOptions options;
    options.model_variance = true;
    options.include_noise = noise;
    const Vector m = testing::RandomVector(e, 0.5, &rng);
    const Matrix s = testing::RandomCovariance(e, 0.2, &rng);
    const BlockForward fwd = [&](const Vector& mm, const Matrix& ss, const Vector&, Vector* y) {
      GaussianPrediction p;
      if (!PredictGaussian(gp, mm, ss, options, &p).ok()) return false;
      y->resize(d + d * d + e * d);
      *y << p.mean, Flatten(p.cov), Flatten(p.cross);
      return true;
    };
    const BlockBackward bwd = [&](const Vector& mm, const Matrix& ss, const Vector&,
                                  const Vector& yb, Vector* mb, Matrix* sb, Vector*) {
      const Vector mean_bar = yb.head(d);
      const Matrix cov_bar = Eigen::Map<const Matrix>(yb.data() + d, d, d);
      const Matrix cross_bar = Eigen::Map<const Matrix>(yb.data() + d + d * d, e, d);
      return PredictGaussianBackward(gp, mm, ss, options, mean_bar, cov_bar, cross_bar, mb, sb,
                                     nullptr, nullptr)
          .ok();
    };
    const diff::CheckResult r = CheckBlock(fwd, bwd, m, s, Vector(), Tight());
    EXPECT_TRUE(r.ok) << "include_noise " << noise << ": " << r.log;
  }
}

// gp2 with derivatives with respect to the support points and beta too.
TEST(GpMomentsTest, Gp2ReverseModeIncludingParametersMatchesFiniteDifferences) {
  std::mt19937_64 rng(3);
  const int n = 8, e = 3, d = 2;
  const GaussianInputGp gp0 = testing::MakeTestGp(n, e, d, &rng);
  GaussianPredictionOptions options;
  options.model_variance = false;
  options.jitter = 1e-6;
  const Vector m = testing::RandomVector(e, 0.5, &rng);
  const Matrix s = testing::RandomCovariance(e, 0.3, &rng);
  Vector theta(n * e + n * d);
  theta << Eigen::Map<const Vector>(gp0.inputs.data(), n * e), Flatten(gp0.beta);
  auto make_gp = [&](const Vector& th) {
    GaussianInputGp gp = gp0;
    gp.inputs = Eigen::Map<const RowMatrix>(th.data(), n, e);
    gp.beta = Eigen::Map<const Matrix>(th.data() + n * e, n, d);
    return gp;
  };
  const BlockForward fwd = [&](const Vector& mm, const Matrix& ss, const Vector& th, Vector* y) {
    GaussianPrediction p;
    if (!PredictGaussian(make_gp(th), mm, ss, options, &p).ok()) return false;
    y->resize(d + d * d + e * d);
    *y << p.mean, Flatten(p.cov), Flatten(p.cross);
    return true;
  };
  const BlockBackward bwd = [&](const Vector& mm, const Matrix& ss, const Vector& th,
                                const Vector& yb, Vector* mb, Matrix* sb, Vector* thb) {
    const Vector mean_bar = yb.head(d);
    const Matrix cov_bar = Eigen::Map<const Matrix>(yb.data() + d, d, d);
    const Matrix cross_bar = Eigen::Map<const Matrix>(yb.data() + d + d * d, e, d);
    RowMatrix xb;
    Matrix bb;
    if (!PredictGaussianBackward(make_gp(th), mm, ss, options, mean_bar, cov_bar, cross_bar, mb,
                                 sb, &xb, &bb)
             .ok()) {
      return false;
    }
    thb->resize(th.size());
    *thb << Eigen::Map<const Vector>(xb.data(), n * e), Flatten(bb);
    return true;
  };
  const diff::CheckResult r = CheckBlock(fwd, bwd, m, s, theta, Tight());
  EXPECT_TRUE(r.ok) << r.log;
}

// A deliberately wrong derivative must fail: (a) one entry off by 0.1 %;
// (b) the classic bug of not counting an off-diagonal covariance entry twice.
// The length-scale adjoint (per output, the outputs' length-scales differ):
// <mean_bar, mean> + <cov_bar, cov> + <cross_bar, cross> against central
// differences in every inverse squared length-scale, for gp0 (model
// variance) and gp2 (mean function only, jitter), at a correlated input.
TEST(GpMomentsTest, LengthscaleAdjointMatchesFiniteDifferences) {
  std::mt19937_64 rng(14);
  const int n = 15, e = 3, d = 3;
  const GaussianInputGp base = testing::MakeTestGp(n, e, d, &rng);
  ASSERT_NE(base.inv_lengthscale_sq(0, 0), base.inv_lengthscale_sq(1, 0));
  const Vector m = testing::RandomVector(e, 0.5, &rng);
  const Matrix s = testing::RandomCovariance(e, 0.3, &rng);
  const Vector mean_bar = testing::RandomVector(d, 1.0, &rng);
  const Matrix cov_bar = testing::RandomCovariance(d, 1.0, &rng) - 0.5 * Matrix::Identity(d, d);
  Matrix cross_bar(e, d);
  for (int a = 0; a < d; ++a) cross_bar.col(a) = testing::RandomVector(e, 1.0, &rng);
  for (bool model_variance : {true, false}) {
    GaussianPredictionOptions options;
    options.model_variance = model_variance;
    options.jitter = model_variance ? 0.0 : 1e-6;
    const diff::VectorFunction f = [&](const Vector& il, Vector* out) {
      GaussianInputGp gp = base;
      gp.inv_lengthscale_sq = Eigen::Map<const RowMatrix>(il.data(), d, e);
      GaussianPrediction p;
      if (!PredictGaussian(gp, m, s, options, &p).ok()) return false;
      *out = Vector::Constant(1, mean_bar.dot(p.mean) + cov_bar.cwiseProduct(p.cov).sum() +
                                     cross_bar.cwiseProduct(p.cross).sum());
      return true;
    };
    RowMatrix il_bar;
    ASSERT_TRUE(PredictGaussianLengthscaleAdjoint(base, m, s, options, mean_bar, cov_bar,
                                                  cross_bar, &il_bar)
                    .ok());
    const Vector il = Eigen::Map<const Vector>(base.inv_lengthscale_sq.data(), d * e);
    const Vector g = Eigen::Map<const Vector>(il_bar.data(), d * e);
    const diff::CheckResult r = diff::CheckJacobian(f, il, g.transpose(), Tight());
    EXPECT_TRUE(r.ok) << (model_variance ? "gp0: " : "gp2: ") << r.log;
    EXPECT_GT(g.cwiseAbs().maxCoeff(), 1e-3);
  }
}

TEST(GpMomentsTest, WrongDerivativesAreRejected) {
  std::mt19937_64 rng(4);
  const int n = 20, e = 3, d = 2;
  const GaussianInputGp gp = testing::MakeTestGp(n, e, d, &rng);
  GaussianPredictionOptions options;
  const Vector m = testing::RandomVector(e, 0.5, &rng);
  const Matrix s = testing::RandomCovariance(e, 0.3, &rng);
  const BlockForward fwd = [&](const Vector& mm, const Matrix& ss, const Vector&, Vector* y) {
    GaussianPrediction p;
    if (!PredictGaussian(gp, mm, ss, options, &p).ok()) return false;
    y->resize(d + d * d);
    *y << p.mean, Flatten(p.cov);
    return true;
  };
  const BlockBackward bwd = [&](const Vector& mm, const Matrix& ss, const Vector&,
                                const Vector& yb, Vector* mb, Matrix* sb, Vector*) {
    const Matrix cov_bar = Eigen::Map<const Matrix>(yb.data() + d, d, d);
    return PredictGaussianBackward(gp, mm, ss, options, yb.head(d), cov_bar,
                                   Matrix::Zero(e, d), mb, sb, nullptr, nullptr)
        .ok();
  };
  EXPECT_TRUE(CheckBlock(fwd, bwd, m, s, Vector(), Tight()).ok);
  EXPECT_FALSE(CheckBlock(fwd, bwd, m, s, Vector(), Tight(), /*symmetrise=*/false).ok);
  const BlockBackward off_by_a_bit = [&](const Vector& mm, const Matrix& ss, const Vector& th,
                                         const Vector& yb, Vector* mb, Matrix* sb, Vector* thb) {
    if (!bwd(mm, ss, th, yb, mb, sb, thb)) return false;
    (*mb)(1) *= 1.001;
    return true;
  };
  const diff::CheckResult r = CheckBlock(fwd, off_by_a_bit, m, s, Vector(), Tight());
  EXPECT_FALSE(r.ok);
  EXPECT_LT(r.worst_col, e);
}

// ---------------------------------------------------------------- policy

TEST(PolicyMomentsTest, ReverseModeMatchesFiniteDifferences) {
  std::mt19937_64 rng(5);
  RbfPolicyShape shape;
  shape.num_basis = 6;
  shape.input_dim = 5;
  shape.max_force = 10.0;
  shape.jitter = 1e-6;
  Vector params(shape.num_parameters());
  params.head(shape.num_basis * shape.input_dim) =
      testing::RandomVector(shape.num_basis * shape.input_dim, 0.6, &rng);
  params.segment(shape.num_basis * shape.input_dim, shape.input_dim) =
      testing::RandomVector(shape.input_dim, 0.2, &rng);
  params.tail(shape.num_basis) = testing::RandomVector(shape.num_basis, 0.5, &rng);
  const Vector m = testing::RandomVector(5, 0.4, &rng);
  const Matrix s = testing::RandomCovariance(5, 0.1, &rng);
  for (const bool squashed : {true, false}) {
    const BlockForward fwd = [&](const Vector& mm, const Matrix& ss, const Vector& th, Vector* y) {
      PolicyMoments pm;
      if (!PolicyAtGaussian(shape, th, mm, ss, &pm).ok()) return false;
      y->resize(2 + 5);
      if (squashed) {
        *y << pm.sat.mean, pm.sat.var, pm.u_cross;
      } else {
        *y << pm.a_mean, pm.a_var, pm.a_cross;
      }
      return true;
    };
    const BlockBackward bwd = [&](const Vector& mm, const Matrix& ss, const Vector& th,
                                  const Vector& yb, Vector* mb, Matrix* sb, Vector* thb) {
      thb->setZero(th.size());
      const Vector cross_bar = yb.tail(5);
      if (squashed) {
        return PolicyAtGaussianBackward(shape, th, mm, ss, yb(0), yb(1), cross_bar, mb, sb, thb)
            .ok();
      }
      return UnsquashedPolicyBackward(shape, th, mm, ss, yb(0), yb(1), cross_bar, mb, sb, thb)
          .ok();
    };
    const diff::CheckResult r = CheckBlock(fwd, bwd, m, s, params, Tight());
    EXPECT_TRUE(r.ok) << "squashed " << squashed << ": " << r.log;
  }
}

TEST(PolicyMomentsTest, PseudoTargetParameterisationMatchesFiniteDifferences) {
  std::mt19937_64 rng(9);
  RbfPolicyShape shape;
  shape.num_basis = 5;
  shape.input_dim = 3;
  const int n = shape.num_parameters();
  Vector pilco(n);
  pilco.head(15) = testing::RandomVector(15, 0.8, &rng);
  pilco.segment(15, 3) = testing::RandomVector(3, 0.2, &rng);
  pilco.tail(5) = testing::RandomVector(5, 0.3, &rng);
  const diff::VectorFunction f = [&](const Vector& x, Vector* y) {
    return PseudoTargetsToWeights(shape, x, y).ok();
  };
  Matrix analytic(n, n);
  for (int r = 0; r < n; ++r) {
    Vector bar = Vector::Zero(n), out;
    bar(r) = 1.0;
    ASSERT_TRUE(PseudoTargetsBackward(shape, pilco, bar, &out).ok());
    analytic.row(r) = out.transpose();
  }
  diff::CheckOptions o = Tight();
  o.relative_tolerance = 1e-5;
  const diff::CheckResult r = diff::CheckJacobian(f, pilco, analytic, o);
  EXPECT_TRUE(r.ok) << r.log;
  // Weights solve (K + 1e-4 I) w = y.
  Vector params;
  ASSERT_TRUE(PseudoTargetsToWeights(shape, pilco, &params).ok());
  EXPECT_TRUE(params.head(18).isApprox(pilco.head(18)));
  Vector back;  // and back (the optimiser's way in)
  ASSERT_TRUE(WeightsToPseudoTargets(shape, params, &back).ok());
  EXPECT_TRUE(back.isApprox(pilco, 1e-9)) << (back - pilco).transpose();
}

// Two controls (the double pendulum's torques): the policy's squashed
// moments [E u; Cov u; u_cross] against finite differences of (m, s, theta),
// theta = [centres, log l, weights C x 2]; and the pseudo-targets with two
// columns.
RbfPolicyShape TwoControlShape() {
  RbfPolicyShape shape;
  shape.num_basis = 6;
  shape.input_dim = 5;
  shape.jitter = 1e-6;
  shape.max_controls = Eigen::Vector2d(2.0, 3.5);
  return shape;
}

TEST(PolicyMomentsTest, TwoControlsReverseModeMatchesFiniteDifferences) {
  std::mt19937_64 rng(15);
  const RbfPolicyShape shape = TwoControlShape();
  const int c = 6, e = 5, f = 2;
  ASSERT_EQ(shape.num_parameters(), c * e + e + c * f);
  Vector params(shape.num_parameters());
  params.head(c * e) = testing::RandomVector(c * e, 0.6, &rng);
  params.segment(c * e, e) = testing::RandomVector(e, 0.2, &rng);
  params.tail(c * f) = testing::RandomVector(c * f, 0.8, &rng);
  const Vector m = testing::RandomVector(e, 0.4, &rng);
  const Matrix s = testing::RandomCovariance(e, 0.1, &rng);
  const BlockForward fwd = [&](const Vector& mm, const Matrix& ss, const Vector& th, Vector* y) {
    MultiPolicyMoments pm;
    if (!MultiPolicyAtGaussian(shape, th, mm, ss, &pm).ok()) return false;
    y->resize(f + f * f + e * f);
    *y << pm.sat.mean, Flatten(pm.sat.cov), Flatten(pm.u_cross);
    return true;
  };
  const BlockBackward bwd = [&](const Vector& mm, const Matrix& ss, const Vector& th,
                                const Vector& yb, Vector* mb, Matrix* sb, Vector* thb) {
    thb->setZero(th.size());
    const Matrix cov_bar = Eigen::Map<const Matrix>(yb.data() + f, f, f);
    const Matrix cross_bar = Eigen::Map<const Matrix>(yb.data() + f + f * f, e, f);
    return MultiPolicyAtGaussianBackward(shape, th, mm, ss, yb.head(f), cov_bar, cross_bar, mb, sb,
                                         thb)
        .ok();
  };
  const diff::CheckResult r = CheckBlock(fwd, bwd, m, s, params, Tight());
  EXPECT_TRUE(r.ok) << r.log;
  MultiPolicyMoments pm;
  ASSERT_TRUE(MultiPolicyAtGaussian(shape, params, m, s, &pm).ok());
  EXPECT_GT(std::abs(pm.sat.cov(0, 1)), 1e-4) << "the two torques should be correlated";

  // Each control's unsquashed output is the one-control policy with that
  // control's weight column (the same gp2 on the same scaled centres).
  for (int j = 0; j < f; ++j) {
    RbfPolicyShape one = shape;
    one.max_controls.resize(0);
    one.max_force = shape.max_controls(j);
    Vector p1(one.num_parameters());
    p1.head(c * e + e) = params.head(c * e + e);
    for (int k = 0; k < c; ++k) p1(c * e + e + k) = params(c * e + e + k * f + j);
    PolicyMoments single;
    ASSERT_TRUE(PolicyAtGaussian(one, p1, m, s, &single).ok());
    EXPECT_NEAR(pm.a_mean(j), single.a_mean, 1e-13);
    EXPECT_NEAR(pm.a_cov(j, j), single.a_var, 1e-13);
    EXPECT_NEAR(pm.sat.mean(j), single.sat.mean, 1e-12);
    EXPECT_NEAR(pm.sat.cov(j, j), single.sat.var, 1e-12);
    EXPECT_LT((pm.u_cross.col(j) - single.u_cross).cwiseAbs().maxCoeff(), 1e-12);
  }
}

TEST(PolicyMomentsTest, TwoControlPseudoTargetsMatchFiniteDifferences) {
  std::mt19937_64 rng(16);
  RbfPolicyShape shape;
  shape.num_basis = 5;
  shape.input_dim = 3;
  shape.max_controls = Eigen::Vector2d(2.0, 2.0);
  const int n = shape.num_parameters();
  ASSERT_EQ(n, 15 + 3 + 10);
  Vector pilco(n);
  pilco.head(15) = testing::RandomVector(15, 0.8, &rng);
  pilco.segment(15, 3) = testing::RandomVector(3, 0.2, &rng);
  pilco.tail(10) = testing::RandomVector(10, 0.3, &rng);
  const diff::VectorFunction f = [&](const Vector& x, Vector* y) {
    return PseudoTargetsToWeights(shape, x, y).ok();
  };
  Matrix analytic(n, n);
  for (int r = 0; r < n; ++r) {
    Vector bar = Vector::Zero(n), out;
    bar(r) = 1.0;
    ASSERT_TRUE(PseudoTargetsBackward(shape, pilco, bar, &out).ok());
    analytic.row(r) = out.transpose();
  }
  diff::CheckOptions o = Tight();
  o.relative_tolerance = 1e-5;  // as the one-control test
  const diff::CheckResult r = diff::CheckJacobian(f, pilco, analytic, o);
  EXPECT_TRUE(r.ok) << r.log;
  // Each weight column solves (K + 1e-4 I) w_j = y_j: the one-control
  // solve of that column.
  Vector params;
  ASSERT_TRUE(PseudoTargetsToWeights(shape, pilco, &params).ok());
  for (int j = 0; j < 2; ++j) {
    RbfPolicyShape one = shape;
    one.max_controls.resize(0);
    Vector p1(one.num_parameters()), w1;
    p1.head(18) = pilco.head(18);
    for (int k = 0; k < 5; ++k) p1(18 + k) = pilco(18 + 2 * k + j);
    ASSERT_TRUE(PseudoTargetsToWeights(one, p1, &w1).ok());
    for (int k = 0; k < 5; ++k) EXPECT_NEAR(params(18 + 2 * k + j), w1(18 + k), 1e-12);
  }
  // WeightsToPseudoTargets inverts it (the optimiser's way in), both controls.
  Vector back;
  ASSERT_TRUE(WeightsToPseudoTargets(shape, params, &back).ok());
  EXPECT_TRUE(back.isApprox(pilco, 1e-9)) << (back - pilco).transpose();
}

// ---------------------------------------------------------------- costs

void CheckCost(const gaussian::GaussianCost& cost, const Vector& m, const Matrix& s) {
  const BlockForward fwd = [&](const Vector& mm, const Matrix& ss, const Vector&, Vector* y) {
    gaussian::CostMoments c;
    if (!cost.Evaluate(mm, ss, false, &c).ok()) return false;
    *y = Vector::Constant(1, c.mean);
    return true;
  };
  const BlockBackward bwd = [&](const Vector& mm, const Matrix& ss, const Vector&,
                                const Vector& yb, Vector* mb, Matrix* sb, Vector*) {
    gaussian::CostMoments c;
    if (!cost.Evaluate(mm, ss, true, &c).ok()) return false;
    *mb = yb(0) * c.dmean_dm;
    *sb = yb(0) * c.dmean_dS;
    return true;
  };
  const diff::CheckResult r = CheckBlock(fwd, bwd, m, s, Vector(), Tight());
  EXPECT_TRUE(r.ok) << r.log;
}

TEST(ExpectedCostTest, AngleCostGradientMatchesFiniteDifferences) {
  std::mt19937_64 rng(6);
  const Vector target = Eigen::Vector4d(0, M_PI, 0, 0);
  const Matrix q = Eigen::Vector4d(1, 1, 0, 0).asDiagonal();
  auto cost = gaussian::GaussianCost::Angle(target, q);
  ASSERT_TRUE(cost.ok());
  CheckCost(*cost, Eigen::Vector4d(0.2, 2.5, 0.3, -0.4), testing::RandomCovariance(4, 0.2, &rng));
}

TEST(ExpectedCostTest, TipCostGradientMatchesFiniteDifferences) {
  std::mt19937_64 rng(7);
  auto cost = gaussian::GaussianCost::Tip(4, 0, 1, 0.5, 0.25);
  ASSERT_TRUE(cost.ok());
  CheckCost(*cost, Eigen::Vector4d(0.2, 2.5, 0.3, -0.4), testing::RandomCovariance(4, 0.05, &rng));
  CheckCost(*cost, Eigen::Vector4d(-0.1, 0.1, 0.0, 0.0), 1e-4 * Matrix::Identity(4, 4));
}

// PILCO's lossSat on the pendulum's z = [dtheta, theta, sin, cos] with two
// widths (the mean of their costs), and on a raw state (no angle).
TEST(ExpectedCostTest, SaturatingCostGradientMatchesFiniteDifferences) {
  std::mt19937_64 rng(8);
  Matrix q_z = Matrix::Zero(4, 4);
  q_z(2, 2) = q_z(3, 3) = 1.0;  // l^2 on (sin, cos), l = 1
  const Vector target_z = Eigen::Vector4d(0, M_PI, std::sin(M_PI), std::cos(M_PI));
  auto pendulum = gaussian::GaussianCost::Saturating(2, 1, q_z, target_z, {0.5, 1.5});
  ASSERT_TRUE(pendulum.ok()) << pendulum.status();
  CheckCost(*pendulum, Eigen::Vector2d(0.3, 2.5), testing::RandomCovariance(2, 0.1, &rng));
  CheckCost(*pendulum, Eigen::Vector2d(-0.1, 0.2), 1e-4 * Matrix::Identity(2, 2));
  const Matrix a = testing::RandomCovariance(3, 1.0, &rng);  // a PSD Q on a raw 3-state
  auto raw = gaussian::GaussianCost::Saturating(3, -1, a, Eigen::Vector3d(0.1, -0.2, 0.3), {0.7});
  ASSERT_TRUE(raw.ok()) << raw.status();
  CheckCost(*raw, Eigen::Vector3d(0.5, 0.0, -0.4), testing::RandomCovariance(3, 0.3, &rng));
}

// The cart-pole's saturating cost on z equals the tip cost (loss_cp): the
// same closed form, moments and gradients.
TEST(ExpectedCostTest, SaturatingCostOnTheCartPoleIsTheTipCost) {
  const double l = 0.5, w = 0.25;
  Matrix c = Matrix::Zero(2, 6);  // d = C (z - z_t) with z = [s, beta, s', beta', sin, cos]
  c(0, 0) = 1.0;
  c(0, 4) = l;
  c(1, 5) = l;
  Vector target_z = Vector::Zero(6);
  target_z(1) = M_PI;
  target_z(4) = std::sin(M_PI);
  target_z(5) = std::cos(M_PI);
  auto saturating = gaussian::GaussianCost::Saturating(4, 1, c.transpose() * c, target_z, {w});
  auto tip = gaussian::GaussianCost::Tip(4, 0, 1, l, w);
  ASSERT_TRUE(saturating.ok() && tip.ok());
  std::mt19937_64 rng(9);
  for (int trial = 0; trial < 5; ++trial) {
    const Vector m = testing::RandomVector(4, 1.0, &rng);
    const Matrix s = testing::RandomCovariance(4, 0.05, &rng);
    gaussian::CostMoments a, b;
    ASSERT_TRUE(saturating->Evaluate(m, s, true, &a).ok());
    ASSERT_TRUE(tip->Evaluate(m, s, true, &b).ok());
    EXPECT_NEAR(a.mean, b.mean, 1e-12);
    EXPECT_NEAR(a.var, b.var, 1e-12);
    EXPECT_TRUE(a.dmean_dm.isApprox(b.dmean_dm, 1e-9)) << a.dmean_dm.transpose() << "\n"
                                                       << b.dmean_dm.transpose();
    EXPECT_TRUE(a.dmean_dS.isApprox(b.dmean_dS, 1e-9));
  }
}

// Without angles the closed form is exact: it matches the Monte Carlo mean
// of the cost itself (two widths: the mean of their costs), within 4
// standard errors; and bad inputs are refused by name.
TEST(ExpectedCostTest, SaturatingCostWithoutAnglesIsTheExpectationOfTheCost) {
  std::mt19937_64 rng(10);
  const Matrix q = testing::RandomCovariance(3, 1.0, &rng);
  const Vector target = Eigen::Vector3d(0.2, -0.1, 0.4);
  const std::vector<double> widths = {0.6, 1.3};
  auto cost = gaussian::GaussianCost::Saturating(3, -1, q, target, widths);
  ASSERT_TRUE(cost.ok());
  const Vector m = Eigen::Vector3d(0.5, 0.3, -0.2);
  const Matrix s = testing::RandomCovariance(3, 0.5, &rng);
  gaussian::CostMoments closed;
  ASSERT_TRUE(cost->Evaluate(m, s, false, &closed).ok());
  const Eigen::LLT<Matrix> chol(s);
  std::normal_distribution<double> normal;
  const int samples = 200000;
  double sum = 0, sum2 = 0;
  for (int i = 0; i < samples; ++i) {
    Vector e(3);
    for (int k = 0; k < 3; ++k) e(k) = normal(rng);
    const Vector x = m + chol.matrixL() * e;
    const Vector d = x - target;
    double c = 0;
    for (double w : widths) c += (1.0 - std::exp(-0.5 * d.dot(q * d) / (w * w))) / widths.size();
    sum += c;
    sum2 += c * c;
  }
  const double mean = sum / samples;
  const double se = std::sqrt((sum2 / samples - mean * mean) / samples);
  EXPECT_NEAR(closed.mean, mean, 4 * se) << "standard error " << se;
  EXPECT_GT(closed.mean, 0.05);  // not a trivial case
  Matrix not_psd = q;
  not_psd(0, 0) = -1.0;
  EXPECT_NE(gaussian::GaussianCost::Saturating(3, -1, not_psd, target, widths).status().message().find(
                "positive semi-definite"),
            std::string::npos);
  EXPECT_NE(gaussian::GaussianCost::Saturating(3, -1, q, target, {0.0}).status().message().find("width"),
            std::string::npos);
  EXPECT_FALSE(gaussian::GaussianCost::Saturating(3, 1, q, target, widths).ok());  // z would be 5-dim
}

// PILCO's lossSat on z = [x, sin x_a1, cos x_a1, sin x_a2, cos x_a2, ...]
// with several angles (the cart-double-pendulum's 2, 3 here) and a full,
// general PSD Q on z with two widths: E[c] through the joint trig block, its
// gradient against central differences. A gradient that leaves out the
// pair moments' dependence on S_kl (the covariance between two angles) is
// rejected: the several-angle path is really exercised.
TEST(ExpectedCostTest, SaturatingCostWithSeveralAnglesMatchesFiniteDifferences) {
  std::mt19937_64 rng(31);
  for (const std::vector<int>& angles : {std::vector<int>{1, 2}, std::vector<int>{0, 2, 3}}) {
    const int d = 5, z = d + 2 * static_cast<int>(angles.size());
    const Matrix q = testing::RandomCovariance(z, 0.5, &rng);  // full rank, general
    Vector x_t = testing::RandomVector(d, 1.0, &rng);
    Vector target(z);
    target.head(d) = x_t;
    for (size_t k = 0; k < angles.size(); ++k) {
      target(d + 2 * k) = std::sin(x_t(angles[k]));
      target(d + 2 * k + 1) = std::cos(x_t(angles[k]));
    }
    auto cost = gaussian::GaussianCost::Saturating(d, angles, q, target, {0.8, 2.0});
    ASSERT_TRUE(cost.ok()) << cost.status();
    const Vector m = testing::RandomVector(d, 1.0, &rng);
    Matrix s = testing::RandomCovariance(d, 0.2, &rng);
    CheckCost(*cost, m, s);
    CheckCost(*cost, x_t, 1e-6 * Matrix::Identity(d, d));  // near the target

    // The S_kl entry between the first two angles carries a real gradient
    // (the pair moments); zeroing it must fail the check.
    gaussian::CostMoments right;
    ASSERT_TRUE(cost->Evaluate(m, s, true, &right).ok());
    const int a1 = angles[0], a2 = angles[1];
    ASSERT_GT(std::abs(right.dmean_dS(a1, a2)), 1e-4);
    const BlockForward fwd = [&](const Vector& mm, const Matrix& ss, const Vector&, Vector* y) {
      gaussian::CostMoments c;
      if (!cost->Evaluate(mm, ss, false, &c).ok()) return false;
      *y = Vector::Constant(1, c.mean);
      return true;
    };
    const BlockBackward wrong = [&](const Vector& mm, const Matrix& ss, const Vector&,
                                    const Vector& yb, Vector* mb, Matrix* sb, Vector*) {
      gaussian::CostMoments c;
      if (!cost->Evaluate(mm, ss, true, &c).ok()) return false;
      *mb = yb(0) * c.dmean_dm;
      *sb = yb(0) * c.dmean_dS;
      (*sb)(a1, a2) = (*sb)(a2, a1) = 0.0;
      return true;
    };
    EXPECT_FALSE(CheckBlock(fwd, wrong, m, s, Vector(), Tight()).ok);
  }
}

// Several angles: bad index sets are refused by name, and one angle through
// the list overload is the one-angle overload bit for bit.
TEST(ExpectedCostTest, SaturatingCostAngleListIsValidatedAndOneAngleIsUnchanged) {
  std::mt19937_64 rng(32);
  const Matrix q7 = testing::RandomCovariance(7, 0.5, &rng);
  const Vector t7 = testing::RandomVector(7, 1.0, &rng);
  for (const std::vector<int>& bad :
       {std::vector<int>{2, 1}, std::vector<int>{1, 1}, std::vector<int>{-1, 2},
        std::vector<int>{1, 3}}) {
    auto c = gaussian::GaussianCost::Saturating(3, bad, q7, t7, {1.0});
    ASSERT_FALSE(c.ok());
    EXPECT_NE(c.status().message().find("angle indices"), std::string::npos) << c.status();
  }
  // Q of the wrong size for two angles (z = 3 + 4 = 7).
  auto wrong_size = gaussian::GaussianCost::Saturating(3, std::vector<int>{0, 1}, q7.topLeftCorner(5, 5),
                                             t7.head(5), {1.0});
  ASSERT_FALSE(wrong_size.ok());
  EXPECT_NE(wrong_size.status().message().find("7 x 7"), std::string::npos) << wrong_size.status();
  Matrix asym = q7;
  asym(0, 1) += 0.1;
  auto not_sym = gaussian::GaussianCost::Saturating(5, std::vector<int>{0}, asym, t7, {1.0});
  ASSERT_FALSE(not_sym.ok());
  EXPECT_NE(not_sym.status().message().find("symmetric"), std::string::npos);

  const Matrix q6 = q7.topLeftCorner(6, 6);
  auto one = gaussian::GaussianCost::Saturating(4, 1, q6, t7.head(6), {0.5, 1.5});
  auto list = gaussian::GaussianCost::Saturating(4, std::vector<int>{1}, q6, t7.head(6), {0.5, 1.5});
  ASSERT_TRUE(one.ok() && list.ok());
  const Vector m = testing::RandomVector(4, 1.0, &rng);
  const Matrix s = testing::RandomCovariance(4, 0.2, &rng);
  gaussian::CostMoments a, b;
  ASSERT_TRUE(one->Evaluate(m, s, true, &a).ok());
  ASSERT_TRUE(list->Evaluate(m, s, true, &b).ok());
  EXPECT_EQ(a.mean, b.mean);
  EXPECT_EQ(a.var, b.var);
  EXPECT_EQ(a.dmean_dm, b.dmean_dm);
  EXPECT_EQ(a.dmean_dS, b.dmean_dS);
}

// ---------------------------------------------------------------- one step

class StepTest : public ::testing::TestWithParam<int> {};

TEST_P(StepTest, ReverseModeMatchesFiniteDifferences) {
  const int angle = GetParam();
  std::mt19937_64 rng(8);
  const int d = 4, ep = angle >= 0 ? 5 : 4;
  const GaussianInputGp gp = testing::MakeTestGp(25, ep + 1, d, &rng, 1.5);
  PropagationOptions options;
  options.angle_index = angle;
  options.num_basis = 5;
  options.max_force = 10.0;
  const Propagator prop(&gp, options);
  Vector params(prop.num_parameters());
  params.head(5 * ep) = testing::RandomVector(5 * ep, 0.7, &rng);
  params.segment(5 * ep, ep).setConstant(std::log(0.9));
  params.tail(5) = testing::RandomVector(5, 0.5, &rng);
  const Vector m = Eigen::Vector4d(0.1, 0.4, -0.2, 0.3);
  const Matrix s = testing::RandomCovariance(d, 0.05, &rng);
  const BlockForward fwd = [&](const Vector& mm, const Matrix& ss, const Vector& th, Vector* y) {
    Vector mn;
    Matrix sn;
    if (!prop.Step(th, mm, ss, &mn, &sn, nullptr).ok()) return false;
    y->resize(d + d * d);
    *y << mn, Flatten(sn);
    return true;
  };
  const BlockBackward bwd = [&](const Vector& mm, const Matrix& ss, const Vector& th,
                                const Vector& yb, Vector* mb, Matrix* sb, Vector* thb) {
    StepCache cache;
    Vector mn;
    Matrix sn;
    if (!prop.Step(th, mm, ss, &mn, &sn, &cache).ok()) return false;
    thb->setZero(th.size());
    const Matrix snb = Eigen::Map<const Matrix>(yb.data() + d, d, d);
    return prop.StepBackward(th, cache, yb.head(d), snb, mb, sb, thb).ok();
  };
  const diff::CheckResult r = CheckBlock(fwd, bwd, m, s, params, Tight());
  EXPECT_TRUE(r.ok) << r.log;
}

INSTANTIATE_TEST_SUITE_P(WithAndWithoutSinCos, StepTest, ::testing::Values(1, -1));

// One step with several angles: y's pair blocks and the policy and GP inputs
// [x without the angles, (sin, cos) per angle, u] through the whole step.
struct StepAnglesCase {
  int d;
  std::vector<int> angles;
};
class StepAnglesTest : public ::testing::TestWithParam<StepAnglesCase> {};

TEST_P(StepAnglesTest, ReverseModeMatchesFiniteDifferences) {
  const int d = GetParam().d;
  const std::vector<int> angles = GetParam().angles;
  const int ep = d + static_cast<int>(angles.size());
  std::mt19937_64 rng(9);
  const GaussianInputGp gp = testing::MakeTestGp(25, ep + 1, d, &rng, 1.5);
  PropagationOptions options;
  options.angle_indices = angles;
  options.num_basis = 5;
  options.max_force = 10.0;
  ASSERT_TRUE(Propagator::Validate(gp, options).ok()) << Propagator::Validate(gp, options);
  const Propagator prop(&gp, options);
  ASSERT_EQ(prop.policy_input_dim(), ep);
  Vector params(prop.num_parameters());
  params.head(5 * ep) = testing::RandomVector(5 * ep, 0.7, &rng);
  params.segment(5 * ep, ep).setConstant(std::log(0.9));
  params.tail(5) = testing::RandomVector(5, 0.5, &rng);
  const Vector m = testing::RandomVector(d, 0.4, &rng);
  const Matrix s = testing::RandomCovariance(d, 0.05, &rng);
  const BlockForward fwd = [&](const Vector& mm, const Matrix& ss, const Vector& th, Vector* y) {
    Vector mn;
    Matrix sn;
    if (!prop.Step(th, mm, ss, &mn, &sn, nullptr).ok()) return false;
    y->resize(d + d * d);
    *y << mn, Flatten(sn);
    return true;
  };
  const BlockBackward bwd = [&](const Vector& mm, const Matrix& ss, const Vector& th,
                                const Vector& yb, Vector* mb, Matrix* sb, Vector* thb) {
    StepCache cache;
    Vector mn;
    Matrix sn;
    if (!prop.Step(th, mm, ss, &mn, &sn, &cache).ok()) return false;
    thb->setZero(th.size());
    const Matrix snb = Eigen::Map<const Matrix>(yb.data() + d, d, d);
    return prop.StepBackward(th, cache, yb.head(d), snb, mb, sb, thb).ok();
  };
  const diff::CheckResult r = CheckBlock(fwd, bwd, m, s, params, Tight());
  EXPECT_TRUE(r.ok) << r.log;
  // The policy input of a point: the non-angle dims, then (sin, cos) per angle.
  const Vector p = prop.PolicyInput(m);
  int col = 0;
  for (int i = 0; i < d; ++i) {
    if (std::find(angles.begin(), angles.end(), i) == angles.end()) {
      EXPECT_EQ(p(col++), m(i));
    }
  }
  for (int a : angles) {
    EXPECT_EQ(p(col++), std::sin(m(a)));
    EXPECT_EQ(p(col++), std::cos(m(a)));
  }
}

INSTANTIATE_TEST_SUITE_P(Angles, StepAnglesTest,
                         ::testing::Values(StepAnglesCase{4, {1, 3}}, StepAnglesCase{6, {4, 5}}),
                         [](const auto& info) {
                           std::string name = "D" + std::to_string(info.param.d) + "Angles";
                           for (int a : info.param.angles) name += std::to_string(a);
                           return name;
                         });

// One step with two controls (the double pendulum: 4 states, angles 2 and
// 3, two torques): g = [p; u1; u2] with Cov(p, u) (Ep x 2) and Cov(u) from
// GSatJoint, through the whole step against finite differences of (m, S,
// theta), theta with C x 2 weights.
TEST(StepControlsTest, ReverseModeMatchesFiniteDifferences) {
  const int d = 4, ep = 6, f = 2, c = 5;
  std::mt19937_64 rng(11);
  const GaussianInputGp gp = testing::MakeTestGp(25, ep + f, d, &rng, 1.5);
  PropagationOptions options;
  options.angle_indices = {2, 3};
  options.num_basis = c;
  options.max_controls = Eigen::Vector2d(2.0, 3.5);
  ASSERT_TRUE(Propagator::Validate(gp, options).ok()) << Propagator::Validate(gp, options);
  const Propagator prop(&gp, options);
  ASSERT_EQ(prop.control_dim(), f);
  ASSERT_EQ(prop.num_parameters(), c * ep + ep + c * f);
  Vector params(prop.num_parameters());
  params.head(c * ep) = testing::RandomVector(c * ep, 0.7, &rng);
  params.segment(c * ep, ep).setConstant(std::log(0.9));
  params.tail(c * f) = testing::RandomVector(c * f, 0.8, &rng);
  Vector m(d);
  m << 0.2, -0.3, 2.9, 3.3;
  const Matrix s = testing::RandomCovariance(d, 0.05, &rng);
  const BlockForward fwd = [&](const Vector& mm, const Matrix& ss, const Vector& th, Vector* y) {
    Vector mn;
    Matrix sn;
    if (!prop.Step(th, mm, ss, &mn, &sn, nullptr).ok()) return false;
    y->resize(d + d * d);
    *y << mn, Flatten(sn);
    return true;
  };
  const BlockBackward bwd = [&](const Vector& mm, const Matrix& ss, const Vector& th,
                                const Vector& yb, Vector* mb, Matrix* sb, Vector* thb) {
    StepCache cache;
    Vector mn;
    Matrix sn;
    if (!prop.Step(th, mm, ss, &mn, &sn, &cache).ok()) return false;
    thb->setZero(th.size());
    const Matrix snb = Eigen::Map<const Matrix>(yb.data() + d, d, d);
    return prop.StepBackward(th, cache, yb.head(d), snb, mb, sb, thb).ok();
  };
  const diff::CheckResult r = CheckBlock(fwd, bwd, m, s, params, Tight());
  EXPECT_TRUE(r.ok) << r.log;
  // Bad bounds are refused by name.
  options.max_controls = Vector::Constant(1, 2.0);
  EXPECT_NE(Propagator::Validate(gp, options).message().find("max_controls"), std::string::npos);
  options.max_controls = Eigen::Vector3d(2.0, 2.0, 2.0);
  EXPECT_NE(Propagator::Validate(gp, options).message().find("3 controls"), std::string::npos);
}

TEST(StepAnglesTest, BadAngleListsAreRefusedByName) {
  std::mt19937_64 rng(10);
  const GaussianInputGp gp = testing::MakeTestGp(10, 7, 4, &rng, 1.5);
  PropagationOptions options;
  options.angle_indices = {3, 1};
  EXPECT_NE(Propagator::Validate(gp, options).message().find("strictly increasing"), std::string::npos);
  options.angle_indices = {1, 3};
  options.angle_index = 1;
  EXPECT_NE(Propagator::Validate(gp, options).message().find("not both"), std::string::npos);
  options.angle_index = -1;
  options.angle_indices = {1};
  // One angle needs 4 + 1 + 1 inputs, not 7: named with the layout.
  EXPECT_NE(Propagator::Validate(gp, options).message().find("(sin, cos) per angle"), std::string::npos);
}

}  // namespace blocks_test
}  // namespace totalgrad::pilco
