// Stability suite, PILCO extremes (docs/stability.md): zero and nearly
// singular start covariances and an angle variance of 1e3, with the raw angle
// (angle_index -1) and with PILCO's (sin, cos) augmentation. Each must give
// finite, symmetric PSD predictions, J in [0, H], and a gradient that agrees
// with finite differences of J; a singular covariance must be continuous
// with its regularised neighbour.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <memory>

#include <Eigen/Eigenvalues>

#include "core/common/rng.h"
#include "core/diff/gradient_checker.h"
#include "core/gaussian/angle_features.h"
#include "core/pilco/pilco.h"
#include "core/pilco/saturation.h"
#include "core/tasks/cartpole.h"
#include "tests/testutil/testutil.h"

namespace totalgrad::pilco {
namespace pilco_test {

constexpr int kBasis = 8;
constexpr int kHorizon = 6;

// A GP on N real cart-pole transitions from states spread over the swing-up
// region, in the feature space of `angle_index`, with PILCO's initial
// hyperparameters (log l = log std(inputs), sf = std(targets), sn = sf / 10).
GaussianInputGp CartPoleGp(int n, int angle_index, uint64_t seed) {
  Rng rng(seed, Stream::kStudy);
  const tasks::CartPole plant;
  RowMatrix states(n, 4), forces(n, 1), targets(n, 4);
  for (int i = 0; i < n; ++i) {
    tasks::State s;
    s << rng.Uniform(-1, 1), rng.Uniform(-1, 2 * M_PI + 1), rng.Uniform(-3, 3),
        rng.Uniform(-8, 8);
    const double u = rng.Uniform(-10, 10);
    tasks::State next;
    EXPECT_TRUE(plant.Step(s, u, &next).ok());
    states.row(i) = s.transpose();
    forces(i, 0) = u;
    targets.row(i) = (next - s).transpose();
  }
  RowMatrix features;
  gaussian::StatesToFeatures(states, angle_index, &features);
  RowMatrix inputs(n, features.cols() + 1);
  inputs << features, forces;
  const int e = static_cast<int>(inputs.cols());
  RowMatrix log_hyp(4, e + 2);
  auto log_std = [n](const auto& column) {
    const double mean = column.mean();
    return 0.5 * std::log((column.array() - mean).square().sum() / (n - 1));
  };
  for (int a = 0; a < 4; ++a) {
    for (int j = 0; j < e; ++j) log_hyp(a, j) = log_std(inputs.col(j));
    log_hyp(a, e) = log_std(targets.col(a));
    log_hyp(a, e + 1) = log_hyp(a, e) - std::log(10.0);
  }
  absl::StatusOr<GaussianInputGp> gp = GaussianInputGpFromData(inputs, targets, log_hyp);
  EXPECT_TRUE(gp.ok()) << gp.status();
  return *gp;
}

class PilcoExtremes : public ::testing::TestWithParam<int> {  // the angle index
 protected:
  void SetUp() override {
    angle_index_ = GetParam();
    gp_ = CartPoleGp(120, angle_index_, 41);
    problem_.mu0 = Vector::Zero(4);
    problem_.S0 = 0.01 * Matrix::Identity(4, 4);
    problem_.horizon = kHorizon;
    tasks::State target;
    target << 0, M_PI, 0, 0;
    problem_.cost = std::make_shared<gaussian::GaussianCost>(
        *gaussian::GaussianCost::Angle(target, Eigen::Vector4d(1, 1, 0, 0).asDiagonal().toDenseMatrix()));
    problem_.propagation.angle_index = angle_index_;
    problem_.propagation.num_basis = kBasis;
    Rng rng(42, Stream::kPolicyInit);
    absl::StatusOr<Vector> params = InitialPolicyParameters(problem_, &rng);
    ASSERT_TRUE(params.ok()) << params.status();
    params_ = *params;
    // Larger weights than PILCO's 0.1 so that the policy matters.
    params_.tail(kBasis) *= 20.0;
  }

  // Runs Propagate with S0 = s0; checks the prediction is finite, symmetric,
  // PSD and J in [0, H]; returns J and the gradient.
  void Run(const Matrix& s0, double* j, Vector* gradient, Trajectory* out = nullptr) {
    PilcoProblem p = problem_;
    p.S0 = s0;
    absl::StatusOr<Trajectory> tr = Propagate(gp_, p, params_, gradient);
    ASSERT_TRUE(tr.ok()) << tr.status();
    for (size_t t = 0; t < tr->covs.size(); ++t) {
      const Matrix& s = tr->covs[t];
      ASSERT_TRUE(s.allFinite() && tr->means[t].allFinite()) << "step " << t;
      ASSERT_EQ((s - s.transpose()).cwiseAbs().maxCoeff(), 0.0) << "step " << t;
      const double min_eig = Eigen::SelfAdjointEigenSolver<Matrix>(s).eigenvalues().minCoeff();
      ASSERT_GE(min_eig, -1e-12 * (1.0 + s.cwiseAbs().maxCoeff())) << "step " << t;
    }
    ASSERT_TRUE(tr->cost_mean.allFinite() && tr->cost_std.allFinite());
    EXPECT_TRUE((tr->cost_mean.array() >= 0).all() && (tr->cost_mean.array() <= 1).all());
    EXPECT_GE(tr->total_cost, 0);
    EXPECT_LE(tr->total_cost, kHorizon);
    ASSERT_TRUE(gradient == nullptr || gradient->allFinite());
    *j = tr->total_cost;
    if (out != nullptr) *out = *tr;
  }

  // dJ/dtheta at S0 = s0 against central differences of J.
  void ExpectGradientMatchesFiniteDifferences(const Matrix& s0) {
    double j = 0;
    Vector gradient;
    Run(s0, &j, &gradient);
    PilcoProblem p = problem_;
    p.S0 = s0;
    const diff::VectorFunction f = [&](const Vector& theta, Vector* out) {
      absl::StatusOr<Trajectory> tr = Propagate(gp_, p, theta, nullptr);
      if (!tr.ok()) return false;
      *out = Vector::Constant(1, tr->total_cost);
      return true;
    };
    // Entry-wise relative error 1e-4, with an absolute floor of 1e-4 of the
    // largest entry: near-deterministic propagation (S0 = 0, only the
    // policy's 1e-6 jitter) leaves round-off of ~1e-5 |dJ| in central
    // differences of J.
    diff::CheckOptions check;
    check.relative_tolerance = 1e-4;
    check.absolute_tolerance = 1e-4 * std::max(1e-3, gradient.lpNorm<Eigen::Infinity>());
    const diff::CheckResult r = diff::CheckJacobian(f, params_, gradient.transpose(), check);
    EXPECT_TRUE(r.ok) << r.log;
    std::printf("  angle_index %d: J %.6g, |dJ| %.3g, FD max rel error %.2g\n", angle_index_, j,
                gradient.norm(), r.max_relative_error);
  }

  int angle_index_ = -1;
  GaussianInputGp gp_;
  PilcoProblem problem_;
  Vector params_;
};

// A deterministic start (S0 = 0): every block sees a singular input
// covariance; PILCO computes its cross-covariances without inverting one.
TEST_P(PilcoExtremes, ZeroStartCovariance) {
  ExpectGradientMatchesFiniteDifferences(Matrix::Zero(4, 4));
}

// Rank one (exactly singular) and rank one + 1e-14 I: the same J and
// gradient to the size of the regularisation.
TEST_P(PilcoExtremes, NearlySingularStartCovarianceIsContinuous) {
  const Vector v = Eigen::Vector4d(0.1, 0.2, -0.3, 0.5);
  const Matrix rank_one = v * v.transpose();
  double j_singular = 0, j_regular = 0;
  Vector g_singular, g_regular;
  Run(rank_one, &j_singular, &g_singular);
  Run(rank_one + 1e-14 * Matrix::Identity(4, 4), &j_regular, &g_regular);
  EXPECT_NEAR(j_singular, j_regular, 1e-9);
  EXPECT_TRUE(testing::MatricesNear(g_singular, g_regular, 1e-8, 1e-6));
  // Eigenvalues spanning 16 decades.
  Matrix graded = Eigen::Vector4d(1e-2, 1e-18, 1e-6, 1e-10).asDiagonal();
  double j_graded = 0;
  Vector g_graded;
  Run(graded, &j_graded, &g_graded);
  ExpectGradientMatchesFiniteDifferences(rank_one);
}

// Angle variance 1e3 (std ~32 rad, ~5 turns): with (sin, cos) the angle
// moments collapse to E[sin] = E[cos] = 0 (exp(-500) ~ 7e-218, finite, no
// underflow to NaN) and Var = 1/2; with the raw angle the GP sees an input
// spread far beyond its length-scales and reverts towards its prior.
TEST_P(PilcoExtremes, AngleVariance1e3) {
  Matrix s0 = 0.01 * Matrix::Identity(4, 4);
  s0(1, 1) = 1e3;
  ExpectGradientMatchesFiniteDifferences(s0);
  if (angle_index_ < 0) return;
  const Propagator prop(&gp_, problem_.propagation);
  StepCache cache;
  Vector m1;
  Matrix s1;
  TG_ASSERT_OK(prop.Step(params_, problem_.mu0, s0, &m1, &s1, &cache));
  // y = [x; sin beta; cos beta] with beta ~ N(0, 1e3).
  EXPECT_LT(std::abs(cache.y_mean(4)), 1e-200);
  EXPECT_NEAR(cache.y_mean(5), std::exp(-500.0), 1e-230);
  EXPECT_NEAR(cache.y_cov(4, 4), 0.5, 1e-12);
  EXPECT_NEAR(cache.y_cov(5, 5), 0.5, 1e-12);
  EXPECT_TRUE(m1.allFinite() && s1.allFinite());
}

// gSat for a wide Gaussian on the policy's pre-saturation output (the raw
// angle makes a_var reach hundreds): Cov(sin a, sin 3a) used to be formed as
// e^{-5v} expm1(3v), which is 0 * Inf = NaN for v > 236 (fixed in
// core/pilco/saturation.cc). Var[u] must tend to u_max^2 (81 + 1) / 128, the
// mean and C to 0, and the values must be continuous across v = 236.6.
TEST(PilcoSaturation, WideInputVarianceGivesTheLimitNotNaN) {
  const double u = 10.0, limit = u * u * 82.0 / 128.0;
  for (const double v : {150.0, 236.0, 237.0, 272.1, 1e3, 1e6, 1e300}) {
    for (const double m : {-11.16, 0.0, 0.7, 3.0}) {
      const SatMoments s = GSat(m, v, u);
      ASSERT_TRUE(std::isfinite(s.mean) && std::isfinite(s.var) && std::isfinite(s.c))
          << "v " << v << " m " << m;
      EXPECT_NEAR(s.var, limit, 1e-12 * limit) << "v " << v << " m " << m;
      EXPECT_LT(std::abs(s.mean), 1e-30);
      EXPECT_LT(std::abs(s.c), 1e-30);
      EXPECT_TRUE(Dx_GSat(m, v, u).allFinite());
    }
  }
  // Moderate variances keep the closed form to round-off: compare with the
  // textbook expression of Var[u] (no expm1) where it is accurate.
  for (const double v : {0.5, 2.0, 10.0}) {
    const double m = 0.7;
    const double var1 = 0.5 * (1 - std::exp(-2 * v) * std::cos(2 * m)) -
                        std::exp(-v) * std::sin(m) * std::sin(m);
    const double var3 = 0.5 * (1 - std::exp(-18 * v) * std::cos(6 * m)) -
                        std::exp(-9 * v) * std::sin(3 * m) * std::sin(3 * m);
    const double cov13 = 0.5 * (std::exp(-2 * v) * std::cos(2 * m) -
                                std::exp(-8 * v) * std::cos(4 * m)) -
                         std::exp(-5 * v) * std::sin(m) * std::sin(3 * m);
    const double expected = u * u * (81.0 / 64 * var1 + 1.0 / 64 * var3 + 18.0 / 64 * cov13);
    EXPECT_NEAR(GSat(m, v, u).var, expected, 1e-12 * u * u) << v;
  }
}

INSTANTIATE_TEST_SUITE_P(RawAndSinCos, PilcoExtremes, ::testing::Values(-1, 1),
                         [](const ::testing::TestParamInfo<int>& info) {
                           return info.param < 0 ? std::string("RawAngle")
                                                 : std::string("SinCos");
                         });

}  // namespace pilco_test
}  // namespace totalgrad::pilco
