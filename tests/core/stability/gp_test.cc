// Stability suite, GP extremes (docs/stability.md): duplicate inputs, noise
// std 1e-8, length-scales 1e-4 and 1e6, 2000 points, inputs scaled by 1e6,
// and a marginal-likelihood optimisation that runs into line-search
// failures. Each case must give a finite, correct model (with the jitter it
// needed recorded) or a FailedPrecondition that names the output and says
// the kernel matrix is not positive definite.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <cstdio>

#include "core/common/rng.h"
#include "core/gp/gp.h"
#include "core/gp/training.h"
#include "tests/testutil/testutil.h"

namespace totalgrad::gp {
namespace gp_test {

using ::testing::HasSubstr;

// f(x) = sin(2 x_0) + 0.5 x_1 on N uniform inputs in [lo, hi]^2.
struct Data {
  RowMatrix x;
  RowMatrix y;
};

Data MakeData(int n, double lo, double hi, double noise, uint64_t seed) {
  Rng rng(seed, Stream::kStudy);
  Data d{RowMatrix(n, 2), RowMatrix(n, 1)};
  for (int i = 0; i < n; ++i) {
    d.x(i, 0) = rng.Uniform(lo, hi);
    d.x(i, 1) = rng.Uniform(lo, hi);
    d.y(i, 0) = std::sin(2.0 * d.x(i, 0)) + 0.5 * d.x(i, 1) + noise * rng.Normal();
  }
  return d;
}

GpHyperparameters Hyp(double lengthscale, double sf, double sn) {
  GpHyperparameters h;
  h.log_lengthscales = RowMatrix::Constant(1, 2, std::log(lengthscale));
  h.log_signal_std = Vector::Constant(1, std::log(sf));
  h.log_noise_std = Vector::Constant(1, std::log(sn));
  return h;
}

struct Prediction {
  RowMatrix mean, var, dmean, dvar;
  bool Finite() const {
    return mean.allFinite() && var.allFinite() && dmean.allFinite() && dvar.allFinite();
  }
};

Prediction Predict(const GpModel& model, const RowMatrix& z) {
  Prediction p;
  model.Predict(z, PredictOptions{}, &p.mean, &p.var, &p.dmean, &p.dvar);
  return p;
}

// Either a usable model or the documented failure; never a silent bad model.
void ExpectModelOrClearError(const absl::StatusOr<GpModel>& model) {
  if (!model.ok()) {
    EXPECT_EQ(model.status().code(), absl::StatusCode::kFailedPrecondition) << model.status();
    EXPECT_THAT(model.status().message(), HasSubstr("not positive definite"));
    EXPECT_THAT(model.status().message(), HasSubstr("output 0"));
  }
}

// Duplicate inputs with ordinary noise: the model is the limit of nearly
// duplicated inputs (scikit-learn's test_duplicate_input): the same
// predictions as with X[0] moved by 1e-7.
TEST(GpExtremes, DuplicateInputsAreTheLimitOfNearDuplicates) {
  Data d = MakeData(30, -2, 2, 0.05, 1);
  RowMatrix x(31, 2), y(31, 1);
  x.topRows(30) = d.x;
  y.topRows(30) = d.y;
  x.row(30) = d.x.row(0);
  y(30, 0) = d.y(0, 0) + 0.1;
  RowMatrix x_near = x;
  x_near(30, 0) += 1e-7;
  const GpHyperparameters hyp = Hyp(0.7, 1.0, 0.1);
  absl::StatusOr<GpModel> dup = GpModel::Create(x, y, hyp);
  absl::StatusOr<GpModel> near = GpModel::Create(x_near, y, hyp);
  TG_ASSERT_OK(dup.status());
  TG_ASSERT_OK(near.status());
  EXPECT_EQ(dup->jitter(0), 0.0);
  const RowMatrix z = MakeData(20, -2.5, 2.5, 0, 2).x;
  const Prediction a = Predict(*dup, z), b = Predict(*near, z);
  ASSERT_TRUE(a.Finite());
  EXPECT_TRUE(testing::MatricesNear(a.mean, b.mean, 1e-6, 0));
  EXPECT_TRUE(testing::MatricesNear(a.var, b.var, 1e-6, 0));
  // The duplicated point's mean sits between its two targets.
  const Prediction at = Predict(*dup, x.row(0));
  EXPECT_GT(at.mean(0, 0), std::min(y(0, 0), y(30, 0)) - 0.1);
  EXPECT_LT(at.mean(0, 0), std::max(y(0, 0), y(30, 0)) + 0.1);
}

// Noise std 1e-8 on smooth data (K has condition ~1e16 and more) and on
// duplicated inputs with conflicting targets (K singular): jitter is
// recorded, K^-1 stays bounded, and the model still fits its data.
TEST(GpExtremes, NoiseStd1em8UsesRecordedJitterOrFailsClearly) {
  {
    SCOPED_TRACE("smooth data");
    const Data d = MakeData(60, -2, 2, 0.0, 3);
    absl::StatusOr<GpModel> model = GpModel::Create(d.x, d.y, Hyp(1.0, 1.0, 1e-8));
    ExpectModelOrClearError(model);
    ASSERT_TRUE(model.ok());
    // Whether jitter is needed depends on the pivots; either way it is
    // recorded, bounded, and the model must interpolate its data and predict
    // held-out points of the smooth function.
    std::printf("  smooth data, sn 1e-8: jitter %.3g, max |K^-1| %.3g\n", model->jitter(0),
                model->k_inverse(0).cwiseAbs().maxCoeff());
    EXPECT_GE(model->jitter(0), 0.0);
    EXPECT_LE(model->jitter(0), 1e-2);
    const Prediction p = Predict(*model, d.x);
    ASSERT_TRUE(p.Finite());
    EXPECT_LT((p.mean - d.y).cwiseAbs().maxCoeff(), 1e-3);
    EXPECT_TRUE((p.var.array() > 0).all());
    // Held out, it agrees with the better-conditioned sn = 1e-6 model (the
    // posterior is continuous in sn; measured difference ~3e-6).
    const RowMatrix held_out = MakeData(30, -1.5, 1.5, 0.0, 33).x;
    absl::StatusOr<GpModel> reference = GpModel::Create(d.x, d.y, Hyp(1.0, 1.0, 1e-6));
    TG_ASSERT_OK(reference.status());
    const Prediction q = Predict(*model, held_out), r = Predict(*reference, held_out);
    ASSERT_TRUE(q.Finite());
    EXPECT_TRUE(testing::MatricesNear(q.mean, r.mean, 1e-4, 0));
    EXPECT_TRUE(testing::MatricesNear(q.var, r.var, 1e-4, 0));
  }
  {
    SCOPED_TRACE("conflicting duplicates");
    const Data d = MakeData(20, -2, 2, 0.0, 4);
    RowMatrix x(40, 2), y(40, 1);
    x << d.x, d.x;
    y << d.y, (d.y.array() + 0.2).matrix();
    absl::StatusOr<GpModel> model = GpModel::Create(x, y, Hyp(1.0, 1.0, 1e-8));
    ExpectModelOrClearError(model);
    ASSERT_TRUE(model.ok());
    std::printf("  conflicting duplicates, sn 1e-8: jitter %.3g\n", model->jitter(0));
    EXPECT_GT(model->jitter(0), 0.0);
    const Prediction p = Predict(*model, d.x);
    ASSERT_TRUE(p.Finite());
    // The best a model can do is the average of the two targets.
    EXPECT_LT((p.mean.array() - (d.y.array() + 0.1)).abs().maxCoeff(), 0.02);
  }
}

// Length-scale 1e-4 with inputs >= 1e-2 apart: K = (sf^2 + sn^2) I to
// round-off. At the data the mean shrinks y by sf^2 / (sf^2 + sn^2); between
// the data the prediction is exactly the prior.
TEST(GpExtremes, LengthScale1em4RevertsToThePriorBetweenTheData) {
  const int n = 40;
  RowMatrix x(n, 2), y(n, 1);
  for (int i = 0; i < n; ++i) {
    x.row(i) << 0.05 * i, -0.05 * i;
    y(i, 0) = std::cos(0.3 * i);
  }
  const double sf = 1.5, sn = 0.2;
  absl::StatusOr<GpModel> model = GpModel::Create(x, y, Hyp(1e-4, sf, sn));
  TG_ASSERT_OK(model.status());
  EXPECT_EQ(model->jitter(0), 0.0);
  const Prediction at = Predict(*model, x);
  ASSERT_TRUE(at.Finite());
  const double shrink = sf * sf / (sf * sf + sn * sn);
  EXPECT_TRUE(testing::MatricesNear(at.mean, shrink * y, 1e-12, 1e-12));
  RowMatrix between = x.array() + 0.025;
  const Prediction off = Predict(*model, between);
  ASSERT_TRUE(off.Finite());
  EXPECT_EQ(off.mean.cwiseAbs().maxCoeff(), 0.0);
  EXPECT_TRUE(testing::MatricesNear(off.var, RowMatrix::Constant(n, 1, sf * sf + sn * sn),
                                    1e-12, 0));
  EXPECT_EQ(off.dmean.cwiseAbs().maxCoeff(), 0.0);
}

// Length-scale 1e6 over data spread ~4: K = sf^2 11^T + sn^2 I to ~1e-12. The
// GP is a constant: the shrunk mean of y everywhere, with near-zero slope.
// With sn = 1e-8 the matrix is rank one to round-off: recorded jitter.
TEST(GpExtremes, LengthScale1e6IsAConstantModel) {
  const Data d = MakeData(50, -2, 2, 0.1, 5);
  const RowMatrix z = MakeData(10, -3, 3, 0, 6).x;
  {
    const double sf = 1.0, sn = 0.1;
    absl::StatusOr<GpModel> model = GpModel::Create(d.x, d.y, Hyp(1e6, sf, sn));
    TG_ASSERT_OK(model.status());
    const Prediction p = Predict(*model, z);
    ASSERT_TRUE(p.Finite());
    const int n = 50;
    const double expected = d.y.sum() * sf * sf / (n * sf * sf + sn * sn);
    EXPECT_LT((p.mean.array() - expected).abs().maxCoeff(), 1e-6);
    EXPECT_LT(p.dmean.cwiseAbs().maxCoeff(), 1e-5);
  }
  {
    absl::StatusOr<GpModel> model = GpModel::Create(d.x, d.y, Hyp(1e6, 1.0, 1e-8));
    ExpectModelOrClearError(model);
    ASSERT_TRUE(model.ok());
    std::printf("  length-scale 1e6, sn 1e-8: jitter %.3g\n", model->jitter(0));
    EXPECT_GT(model->jitter(0), 0.0);
    const Prediction p = Predict(*model, z);
    ASSERT_TRUE(p.Finite());
    // A constant fitted with noise ~ sqrt(jitter): near the data mean.
    EXPECT_LT((p.mean.array() - d.y.mean()).abs().maxCoeff(), 0.05);
  }
}

// 2000 points (O(N^3) = 8e9 flops to factorise and invert): the model builds,
// with whatever jitter the dense sample needs recorded, and predicts finitely.
TEST(GpExtremes, TwoThousandPointsBuildAndPredict) {
  const Data d = MakeData(2000, -3, 3, 0.05, 7);
  const auto start = std::chrono::steady_clock::now();
  absl::StatusOr<GpModel> model = GpModel::Create(d.x, d.y, Hyp(0.8, 1.0, 0.05));
  const double seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  ExpectModelOrClearError(model);
  ASSERT_TRUE(model.ok());
  std::printf("  N = 2000: Create %.2f s, jitter %.3g\n", seconds, model->jitter(0));
  const Prediction p = Predict(*model, d.x.topRows(100));
  ASSERT_TRUE(p.Finite());
  // Noise 0.05 and a dense sample: the fit is at the noise level.
  const double rms = std::sqrt((p.mean - d.y.topRows(100)).squaredNorm() / 100.0);
  EXPECT_LT(rms, 0.1);
}

// Inputs in micrometres instead of metres (x 1e6). Training from PILCO's
// data-derived start must find the same loss (the NLML and the hypCurb
// penalty are invariant under a change of input units when the
// length-scales follow), and the trained models must predict the same.
TEST(GpExtremes, InputsScaledBy1e6GiveTheSameModel) {
  const Data d = MakeData(60, 1, 3, 0.05, 8);  // not centred: scaled inputs ~1e6..3e6
  const RowMatrix x_scaled = 1e6 * d.x;
  TrainingOptions options;
  options.max_iterations = 60;
  GpHyperparameters hyp = InitialHyperparameters(d.x, d.y);
  GpHyperparameters hyp_scaled = InitialHyperparameters(x_scaled, d.y);
  absl::StatusOr<TrainingSummary> s = TrainHyperparameters(d.x, d.y, options, &hyp);
  absl::StatusOr<TrainingSummary> s_scaled =
      TrainHyperparameters(x_scaled, d.y, options, &hyp_scaled);
  TG_ASSERT_OK(s.status());
  TG_ASSERT_OK(s_scaled.status());
  std::printf("  loss %.12g (m) vs %.12g (um)\n", s->final_loss[0], s_scaled->final_loss[0]);
  EXPECT_NEAR(s->final_loss[0], s_scaled->final_loss[0], 1e-6 * std::abs(s->final_loss[0]));
  EXPECT_TRUE(testing::MatricesNear(hyp.log_lengthscales.array() + std::log(1e6),
                                    hyp_scaled.log_lengthscales, 1e-4, 0));
  absl::StatusOr<GpModel> model = GpModel::Create(d.x, d.y, hyp);
  absl::StatusOr<GpModel> model_scaled = GpModel::Create(x_scaled, d.y, hyp_scaled);
  TG_ASSERT_OK(model.status());
  TG_ASSERT_OK(model_scaled.status());
  const RowMatrix z = MakeData(15, 0.5, 3.5, 0, 9).x;
  const Prediction p = Predict(*model, z), q = Predict(*model_scaled, 1e6 * z);
  ASSERT_TRUE(p.Finite() && q.Finite());
  EXPECT_TRUE(testing::MatricesNear(p.mean, q.mean, 1e-5, 1e-5));
  EXPECT_TRUE(testing::MatricesNear(p.var, q.var, 1e-5, 1e-5));
  // Chain rule: d mean / d z_um = 1e-6 d mean / d z_m.
  EXPECT_TRUE(testing::MatricesNear(p.dmean * 1e-6, q.dmean, 1e-11, 1e-4));
}

// The marginal-likelihood optimiser running into line-search failures:
// noiseless data without the signal-to-noise penalty drive sn -> 0 until K
// is no longer positive definite. Training must catch every failure, count
// it, end at a finite loss no worse than the start, and leave a model that
// builds and predicts.
TEST(GpExtremes, NlmlOptimiserSurvivesLineSearchFailures) {
  const Data d = MakeData(40, -2, 2, 0.0, 10);
  RowMatrix x(80, 2), y(80, 1);
  x << d.x, d.x;  // duplicated, consistent targets: NLML unbounded as sn -> 0
  y << d.y, d.y;
  TrainingOptions options;
  options.max_iterations = 200;
  options.penalty.enabled = false;
  GpHyperparameters hyp = InitialHyperparameters(x, y);
  double start_loss = 0;
  ASSERT_TRUE(PenalisedNlml(x, y.col(0), Vector::Ones(2), hyp.Packed(0), options.penalty,
                            &start_loss, nullptr));
  absl::StatusOr<TrainingSummary> summary = TrainHyperparameters(x, y, options, &hyp);
  TG_ASSERT_OK(summary.status());
  std::printf("  %s\n", summary->BriefReport().c_str());
  EXPECT_GT(summary->line_search_failures, 0);
  EXPECT_GT(summary->non_finite_evaluations, 0);
  EXPECT_TRUE(std::isfinite(summary->final_loss[0]));
  EXPECT_LE(summary->final_loss[0], start_loss);
  EXPECT_TRUE(hyp.log_noise_std.allFinite() && hyp.log_lengthscales.allFinite());
  absl::StatusOr<GpModel> model = GpModel::Create(x, y, hyp);
  ExpectModelOrClearError(model);
  ASSERT_TRUE(model.ok());
  const Prediction p = Predict(*model, d.x);
  ASSERT_TRUE(p.Finite());
  EXPECT_LT((p.mean - d.y).cwiseAbs().maxCoeff(), 1e-2);
}

}  // namespace gp_test
}  // namespace totalgrad::gp
