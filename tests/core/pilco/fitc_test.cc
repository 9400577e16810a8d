// FITC sparse GP (core/gp/fitc.h): agreement with the full GP when the
// inducing inputs are the data, NLML gradient and point-prediction Jacobians
// against finite differences, training, moment matching at a Gaussian input
// against 10^6-sample Monte Carlo, and J / dJ with FITC over 30 steps.
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "core/common/rng.h"
#include "core/diff/gradient_checker.h"
#include "core/gp/fitc.h"
#include "core/gaussian/angle_features.h"
#include "core/gaussian/expected_cost.h"
#include "core/pilco/gp_moments.h"
#include "core/pilco/propagation.h"
#include "tests/core/pilco/pilco_test_util.h"
#include "tests/testutil/testutil.h"

namespace totalgrad::pilco {
namespace fitc_test {

struct Data {
  RowMatrix x, y;
  gp::GpHyperparameters hyp;
  RowMatrix log_hyp;  // D x (E + 2)
};

Data MakeData(int n, int e, int d, uint64_t seed, double noise_std = 0.05) {
  std::mt19937_64 rng(seed);
  std::normal_distribution<double> normal;
  Data data;
  data.x.resize(n, e);
  data.y.resize(n, d);
  for (int i = 0; i < n; ++i) {
    for (int j = 0; j < e; ++j) data.x(i, j) = normal(rng);
    for (int a = 0; a < d; ++a) {
      double v = 0;
      for (int j = 0; j < e; ++j) v += std::sin((a + 1) * 0.6 * data.x(i, j) + 0.2 * j);
      data.y(i, a) = 0.3 * v + 0.05 * normal(rng);
    }
  }
  data.hyp.log_lengthscales.resize(d, e);
  data.hyp.log_signal_std.resize(d);
  data.hyp.log_noise_std.resize(d);
  data.log_hyp.resize(d, e + 2);
  for (int a = 0; a < d; ++a) {
    for (int j = 0; j < e; ++j) data.hyp.log_lengthscales(a, j) = std::log(1.0 + 0.2 * ((a + j) % 3));
    data.hyp.log_signal_std(a) = std::log(0.7 + 0.1 * a);
    data.hyp.log_noise_std(a) = std::log(noise_std);
    data.log_hyp.row(a) << data.hyp.log_lengthscales.row(a), data.hyp.log_signal_std(a),
        data.hyp.log_noise_std(a);
  }
  return data;
}

// Exact up to the 1e-6 ridge on Kmm, whose effect is ~ ridge / sn^2 = 1e-5.
TEST(FitcTest, InducingInputsAtTheDataReproduceTheFullGp) {
  const Data data = MakeData(40, 3, 2, 1, /*noise_std=*/0.3);
  auto fitc = gp::FitcModel::Create(data.x, data.y, data.hyp, data.x);
  TG_ASSERT_OK(fitc.status());
  auto full = GaussianInputGpFromData(data.x, data.y, data.log_hyp);
  TG_ASSERT_OK(full.status());
  // Point predictions at new inputs.
  std::mt19937_64 rng(2);
  const RowMatrix z = testing::GaussianSampler(Vector::Zero(3), Matrix::Identity(3, 3)).Sample(20, &rng);
  RowMatrix mean, var;
  fitc->Predict(z, gp::PredictOptions{0.0}, &mean, &var, nullptr, nullptr);
  // Full GP by hand.
  for (int a = 0; a < 2; ++a) {
    const Vector il = full->inv_lengthscale_sq.row(a).transpose();
    for (int p = 0; p < 20; ++p) {
      Vector k(40);
      for (int i = 0; i < 40; ++i) {
        k(i) = full->signal_var(a) *
               std::exp(-0.5 * (z.row(p) - data.x.row(i)).array().square().matrix().dot(il));
      }
      EXPECT_NEAR(mean(p, a), k.dot(full->beta.col(a)), 3e-5);
      EXPECT_NEAR(var(p, a), full->signal_var(a) - k.dot(full->variance_weights[a] * k), 3e-5);
    }
  }
  // Moment matching at a Gaussian input (gp1 vs gp0).
  const GaussianInputGp sparse = GaussianInputGpFromFitc(*fitc);
  GaussianPrediction ps, pf;
  const Vector m = Eigen::Vector3d(0.2, -0.1, 0.3);
  const Matrix s = 0.2 * Matrix::Identity(3, 3);
  TG_ASSERT_OK(PredictGaussian(sparse, m, s, GaussianPredictionOptions(), &ps));
  TG_ASSERT_OK(PredictGaussian(*full, m, s, GaussianPredictionOptions(), &pf));
  EXPECT_TRUE(::totalgrad::testing::MatricesNear(ps.mean, pf.mean, 3e-5, 0));
  EXPECT_TRUE(::totalgrad::testing::MatricesNear(ps.cov, pf.cov, 3e-5, 0));
  EXPECT_TRUE(::totalgrad::testing::MatricesNear(ps.cross, pf.cross, 3e-5, 0));
}

TEST(FitcTest, NlmlGradientMatchesFiniteDifferences) {
  const Data data = MakeData(50, 3, 2, 3);
  Rng rng(4, Stream::kGpInit);
  const RowMatrix z0 = gp::RandomSubsetOfInputs(data.x, 8, &rng);
  double value;
  RowMatrix grad;
  ASSERT_TRUE(gp::FitcNlml(data.x, data.y, data.hyp, z0, &value, &grad));
  const diff::VectorFunction f = [&](const Vector& x, Vector* out) {
    const RowMatrix z = Eigen::Map<const RowMatrix>(x.data(), 8, 3);
    double v;
    if (!gp::FitcNlml(data.x, data.y, data.hyp, z, &v, nullptr)) return false;
    *out = Vector::Constant(1, v);
    return true;
  };
  const Vector x0 = Eigen::Map<const Vector>(z0.data(), 24);
  const Matrix analytic = Eigen::Map<const Vector>(grad.data(), 24).transpose();
  diff::CheckOptions o;
  o.relative_tolerance = 1e-5;
  o.absolute_tolerance = 1e-6;
  const diff::CheckResult r = diff::CheckJacobian(f, x0, analytic, o);
  EXPECT_TRUE(r.ok) << r.log;
  Matrix wrong = analytic;
  wrong(0, 5) *= 1.01;
  EXPECT_FALSE(diff::CheckJacobian(f, x0, wrong, o).ok);
}

TEST(FitcTest, PredictJacobiansMatchFiniteDifferences) {
  const Data data = MakeData(50, 3, 2, 5);
  Rng rng(6, Stream::kGpInit);
  auto fitc = gp::FitcModel::Create(data.x, data.y, data.hyp,
                                    gp::RandomSubsetOfInputs(data.x, 10, &rng));
  TG_ASSERT_OK(fitc.status());
  const Vector z0 = Eigen::Vector3d(0.3, -0.2, 0.5);
  RowMatrix mean, var, dm, dv;
  fitc->Predict(z0.transpose(), gp::PredictOptions{1.0}, &mean, &var, &dm, &dv);
  const diff::VectorFunction f = [&](const Vector& z, Vector* out) {
    RowMatrix m, v;
    fitc->Predict(z.transpose(), gp::PredictOptions{1.0}, &m, &v, nullptr, nullptr);
    out->resize(4);
    *out << m(0, 0), m(0, 1), v(0, 0), v(0, 1);
    return true;
  };
  Matrix analytic(4, 3);
  analytic.row(0) = dm.row(0).segment(0, 3);
  analytic.row(1) = dm.row(0).segment(3, 3);
  analytic.row(2) = dv.row(0).segment(0, 3);
  analytic.row(3) = dv.row(0).segment(3, 3);
  diff::CheckOptions o;
  o.relative_tolerance = 1e-6;
  o.absolute_tolerance = 1e-8;
  const diff::CheckResult r = diff::CheckJacobian(f, z0, analytic, o);
  EXPECT_TRUE(r.ok) << r.log;
}

TEST(FitcTest, TrainingReducesTheNlml) {
  const Data data = MakeData(80, 3, 2, 7);
  Rng rng(8, Stream::kGpInit);
  RowMatrix z = gp::RandomSubsetOfInputs(data.x, 10, &rng);
  gp::FitcTrainingOptions options;
  options.max_iterations = 50;
  auto summary = gp::TrainInducingInputs(data.x, data.y, data.hyp, options, &z);
  TG_ASSERT_OK(summary.status());
  EXPECT_LT(summary->final_nlml, summary->initial_nlml - 1.0) << summary->BriefReport();
  double check;
  ASSERT_TRUE(gp::FitcNlml(data.x, data.y, data.hyp, z, &check, nullptr));
  EXPECT_DOUBLE_EQ(check, summary->final_nlml);
}

TEST(FitcTest, BadShapesAreNamed) {
  const Data data = MakeData(10, 3, 2, 9);
  auto fitc = gp::FitcModel::Create(data.x, data.y, data.hyp, RowMatrix::Zero(4, 2));
  EXPECT_EQ(fitc.status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_NE(fitc.status().message().find("inducing"), std::string::npos) << fitc.status();
}

// gp1 at a Gaussian input against Monte Carlo of FITC's own point predictive.
TEST(FitcTest, GaussianInputMomentsMatchMonteCarlo) {
  const Data data = MakeData(60, 4, 2, 10);
  Rng rng(11, Stream::kGpInit);
  auto fitc = gp::FitcModel::Create(data.x, data.y, data.hyp,
                                    gp::RandomSubsetOfInputs(data.x, 15, &rng));
  TG_ASSERT_OK(fitc.status());
  const GaussianInputGp sparse = GaussianInputGpFromFitc(*fitc);
  std::mt19937_64 gen(12);
  const Vector m = testing::RandomVector(4, 0.3, &gen);
  const Matrix s = testing::RandomCovariance(4, 0.3, &gen);
  GaussianPrediction pred;
  TG_ASSERT_OK(PredictGaussian(sparse, m, s, GaussianPredictionOptions(), &pred));
  const testing::GaussianSampler sampler(m, s);
  testing::MomentAccumulator acc(4 + 2 + 2);
  Vector shift = Vector::Zero(8);
  shift << m, pred.mean, Vector::Zero(2);
  acc.SetShift(shift);
  for (int done = 0; done < 1000000; done += 100000) {
    const RowMatrix x = sampler.Sample(100000, &gen);
    RowMatrix mean, var;
    fitc->Predict(x, gp::PredictOptions{0.0}, &mean, &var, nullptr, nullptr);
    RowMatrix row(100000, 8);
    row << x, mean, var;
    acc.AddBatch(row);
  }
  const Vector mc_mean = acc.Mean(), mc_se = acc.MeanStdError();
  EXPECT_TRUE(testing::WithinMcError(pred.mean, mc_mean.segment(4, 2), mc_se.segment(4, 2), 5));
  Matrix cov = acc.Cov().block(4, 4, 2, 2), se = acc.CovStdError().block(4, 4, 2, 2);
  cov.diagonal() += mc_mean.tail(2);
  se.diagonal() += mc_se.tail(2);
  EXPECT_TRUE(testing::WithinMcError(pred.cov, cov, se, 5));
  EXPECT_TRUE(testing::WithinMcError(s * pred.cross, acc.Cov().block(0, 4, 4, 2),
                                     acc.CovStdError().block(0, 4, 4, 2), 5));
}

TEST(FitcTest, ChainedGradientWithFitcMatchesFiniteDifferences) {
  // Cart-pole-like dynamics data in the sin/cos representation.
  std::mt19937_64 gen(13);
  std::normal_distribution<double> normal;
  const int n = 80;
  RowMatrix states(n, 4), y(n, 4);
  Vector u(n);
  for (int i = 0; i < n; ++i) {
    states.row(i) << 0.3 * normal(gen), 0.5 * normal(gen), 0.5 * normal(gen), normal(gen);
    u(i) = 3 * normal(gen);
    y.row(i) << 0.1 * states(i, 2), 0.1 * states(i, 3), 0.1 * u(i) - 0.05 * std::sin(states(i, 1)),
        -0.9 * std::sin(states(i, 1)) - 0.1 * u(i) * std::cos(states(i, 1));
  }
  RowMatrix features;
  gaussian::StatesToFeatures(states, 1, &features);
  RowMatrix x(n, 6);
  x << features, u;
  gp::GpHyperparameters hyp;
  hyp.log_lengthscales = RowMatrix::Constant(4, 6, std::log(1.5));
  hyp.log_signal_std = Vector::Constant(4, std::log(0.5));
  hyp.log_noise_std = Vector::Constant(4, std::log(0.01));
  Rng rng(14, Stream::kGpInit);
  auto fitc = gp::FitcModel::Create(x, y, hyp, gp::RandomSubsetOfInputs(x, 25, &rng));
  TG_ASSERT_OK(fitc.status());
  const GaussianInputGp sparse = GaussianInputGpFromFitc(*fitc);
  PropagationOptions options;
  options.angle_index = 1;
  options.num_basis = 5;
  const Propagator prop(&sparse, options);
  auto cost = gaussian::GaussianCost::Tip(4, 0, 1, 0.5, 0.25);
  TG_ASSERT_OK(cost.status());
  Vector params(prop.num_parameters());
  params.head(25) = testing::RandomVector(25, 0.3, &gen);
  params.segment(25, 5).setZero();
  params.tail(5) = testing::RandomVector(5, 0.5, &gen);
  const Vector mu0 = Vector::Zero(4);
  const Matrix s0 = 0.01 * Matrix::Identity(4, 4);
  Trajectory tr;
  Vector grad;
  TG_ASSERT_OK(PredictTrajectory(prop, *cost, params, mu0, s0, 30, &tr, &grad));
  const diff::VectorFunction j = [&](const Vector& th, Vector* out) {
    Trajectory t;
    if (!PredictTrajectory(prop, *cost, th, mu0, s0, 30, &t, nullptr).ok()) return false;
    *out = Vector::Constant(1, t.total_cost);
    return true;
  };
  diff::CheckOptions o;
  o.relative_tolerance = 1e-5;
  o.absolute_tolerance = 1e-7;
  const diff::CheckResult r = diff::CheckJacobian(j, params, grad.transpose(), o);
  EXPECT_TRUE(r.ok) << r.log;
}

}  // namespace fitc_test
}  // namespace totalgrad::pilco
