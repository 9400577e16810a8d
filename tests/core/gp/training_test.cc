#include "core/gp/training.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <Eigen/Cholesky>
#include <cmath>
#include <limits>

#include "core/common/rng.h"
#include "core/diff/gradient_checker.h"
#include "core/gp/gp.h"
#include "core/gp/lbfgs_minimize.h"
#include "tests/testutil/testutil.h"

namespace totalgrad::gp {
namespace training_test {

using ::testing::HasSubstr;

// (N-1)-normalised column std, written independently of training.cc.
Vector ReferenceStd(const RowMatrix& m) {
  Vector s(m.cols());
  for (Eigen::Index c = 0; c < m.cols(); ++c) {
    const double mean = m.col(c).sum() / m.rows();
    double ss = 0;
    for (Eigen::Index r = 0; r < m.rows(); ++r) ss += (m(r, c) - mean) * (m(r, c) - mean);
    s(c) = std::sqrt(ss / (m.rows() - 1));
  }
  return s;
}

struct Data {
  RowMatrix inputs;
  RowMatrix targets;
};

// y0 = sin(2 z1) + 0.5 z2^2 + N(0, noise0^2), y1 = z1 z2 + N(0, noise1^2) on
// [-2, 2]^2, offset in z1 so that centring matters.
Data MakeData(int n, double noise0, double noise1, uint64_t seed) {
  Rng rng(seed, Stream::kStudy);
  Data data;
  data.inputs.resize(n, 2);
  data.targets.resize(n, 2);
  for (int i = 0; i < n; ++i) {
    const double z1 = rng.Uniform(-2, 2), z2 = rng.Uniform(-2, 2);
    data.inputs.row(i) << z1 + 5.0, z2;
    data.targets(i, 0) = std::sin(2 * z1) + 0.5 * z2 * z2 + noise0 * rng.Normal();
    data.targets(i, 1) = z1 * z2 + noise1 * rng.Normal();
  }
  return data;
}

diff::VectorFunction NlmlFunction(const RowMatrix& inputs, const Vector& targets,
                                  const Vector& input_std, const PenaltyOptions& penalty) {
  return [&inputs, targets, input_std, penalty](const Vector& x, Vector* value) {
    double v = 0;
    if (!PenalisedNlml(inputs, targets, input_std, x, penalty, &v, nullptr)) return false;
    *value = Vector::Constant(1, v);
    return true;
  };
}

// The NLML is a sum of O(N) terms of size O(1..100); central differences with
// step 1e-6 carry round-off ~1e-16 * 1e3 / 1e-6 ~ 1e-7 absolute, and
// truncation ~1e-12 * |f'''| (the p = 30 penalty has |f'''| ~ 1e3 at the
// active point below), far below real mistakes (a missing factor 1/2, a sign,
// a dropped penalty term), which are O(1) or larger.
diff::CheckOptions GradientCheckOptions() {
  diff::CheckOptions options;
  options.relative_step = 1e-6;
  options.relative_tolerance = 1e-6;
  options.absolute_tolerance = 1e-6;
  return options;
}

class PenalisedNlmlTest : public ::testing::Test {
 protected:
  void SetUp() override {
    const Data data = MakeData(30, 0.1, 0.1, 1);
    inputs_ = RowMatrix(30, 3);
    inputs_.leftCols(2) = data.inputs;
    Rng rng(2, Stream::kStudy);
    for (int i = 0; i < 30; ++i) inputs_(i, 2) = 10.0 * rng.Normal();  // a wide column
    targets_ = data.targets.col(0);
    input_std_ = ReferenceStd(inputs_);
  }

  diff::CheckResult Check(const Vector& x, const PenaltyOptions& penalty) {
    double value = 0;
    Vector gradient;
    EXPECT_TRUE(PenalisedNlml(inputs_, targets_, input_std_, x, penalty, &value, &gradient));
    EXPECT_TRUE(std::isfinite(value));
    return diff::CheckJacobian(NlmlFunction(inputs_, targets_, input_std_, penalty), x,
                               gradient.transpose(), GradientCheckOptions());
  }

  RowMatrix inputs_;
  Vector targets_;
  Vector input_std_;
};

TEST_F(PenalisedNlmlTest, GradientMatchesFiniteDifferencesWithoutPenalty) {
  PenaltyOptions off;
  off.enabled = false;
  Vector x(5);
  x << std::log(0.8), std::log(1.5), std::log(4.0), std::log(1.1), std::log(0.15);
  const diff::CheckResult result = Check(x, off);
  EXPECT_TRUE(result.ok) << result.log;
  // Each component is checked, and none is trivially zero.
  EXPECT_GT(result.analytic.cwiseAbs().minCoeff(), 1e-3) << result.analytic;
}

TEST_F(PenalisedNlmlTest, GradientMatchesFiniteDifferencesWithPenalty) {
  const PenaltyOptions on;
  // Near PILCO's initialisation the penalty is negligible but evaluated.
  Vector x(5);
  x << std::log(input_std_(0)), std::log(input_std_(1)), std::log(input_std_(2)), 0.2, -2.0;
  diff::CheckResult result = Check(x, on);
  EXPECT_TRUE(result.ok) << result.log;

  // Active penalty: log l_1 1.15 log(100) above log std_1, log l_2 1.1 log(100)
  // below log std_2 (odd power of a negative number in the gradient), and
  // sf/sn = 1000^1.08.
  Vector active(5);
  active << std::log(input_std_(0)) + 1.15 * std::log(100.0),
      std::log(input_std_(1)) - 1.1 * std::log(100.0), std::log(input_std_(2)), 0.5,
      0.5 - 1.08 * std::log(1000.0);
  PenaltyOptions off;
  off.enabled = false;
  double with_penalty = 0, without_penalty = 0;
  ASSERT_TRUE(PenalisedNlml(inputs_, targets_, input_std_, active, on, &with_penalty, nullptr));
  ASSERT_TRUE(
      PenalisedNlml(inputs_, targets_, input_std_, active, off, &without_penalty, nullptr));
  // 1.15^30 + 1.1^30 + 1.08^30 = 66 + 17 + 10: the penalty really is active.
  EXPECT_NEAR(with_penalty - without_penalty,
              std::pow(1.15, 30) + std::pow(1.1, 30) + std::pow(1.08, 30), 1e-8);
  result = Check(active, on);
  EXPECT_TRUE(result.ok) << result.log;
}

TEST_F(PenalisedNlmlTest, WrongGradientFailsTheCheck) {
  const PenaltyOptions on;
  PenaltyOptions off;
  off.enabled = false;
  Vector active(5);
  active << std::log(input_std_(0)) + 1.15 * std::log(100.0), std::log(input_std_(1)),
      std::log(input_std_(2)), 0.5, 0.5 - 1.08 * std::log(1000.0);
  double value = 0;
  Vector gradient;
  // The NLML gradient without the penalty's contribution.
  ASSERT_TRUE(PenalisedNlml(inputs_, targets_, input_std_, active, off, &value, &gradient));
  EXPECT_FALSE(diff::CheckJacobian(NlmlFunction(inputs_, targets_, input_std_, on), active,
                                   gradient.transpose(), GradientCheckOptions())
                   .ok);
  // The log sn component with the wrong sign of the trace term.
  ASSERT_TRUE(PenalisedNlml(inputs_, targets_, input_std_, active, on, &value, &gradient));
  double unpenalised_sn = 0;
  {
    Vector g_off;
    ASSERT_TRUE(PenalisedNlml(inputs_, targets_, input_std_, active, off, &value, &g_off));
    unpenalised_sn = g_off(4);
  }
  gradient(4) -= 2 * unpenalised_sn;
  EXPECT_FALSE(diff::CheckJacobian(NlmlFunction(inputs_, targets_, input_std_, on), active,
                                   gradient.transpose(), GradientCheckOptions())
                   .ok);
}

TEST_F(PenalisedNlmlTest, ValueMatchesDirectFormula) {
  PenaltyOptions off;
  off.enabled = false;
  Vector x(5);
  x << std::log(0.8), std::log(1.5), std::log(4.0), std::log(1.1), std::log(0.15);
  const int n = 30;
  Matrix k(n, n);
  for (int i = 0; i < n; ++i)
    for (int j = 0; j < n; ++j) {
      double d2 = 0;
      for (int m = 0; m < 3; ++m) d2 += std::pow((inputs_(i, m) - inputs_(j, m)) / std::exp(x(m)), 2);
      k(i, j) = std::exp(2 * x(3)) * std::exp(-0.5 * d2) + (i == j ? std::exp(2 * x(4)) : 0.0);
    }
  const Eigen::LDLT<Matrix> ldlt(k);
  const double expected = 0.5 * targets_.dot(ldlt.solve(targets_)) +
                          0.5 * ldlt.vectorD().array().log().sum() +
                          0.5 * n * std::log(2 * M_PI);
  double value = 0;
  ASSERT_TRUE(PenalisedNlml(inputs_, targets_, input_std_, x, off, &value, nullptr));
  EXPECT_NEAR(value, expected, 1e-9 * std::abs(expected));
}

TEST_F(PenalisedNlmlTest, ReportsNonPositiveDefiniteK) {
  Vector x(5);
  x << 0.0, 0.0, 0.0, -400.0, -400.0;  // sf^2 = sn^2 = 0 after underflow: K = 0
  double value = 0;
  Vector gradient;
  EXPECT_FALSE(PenalisedNlml(inputs_, targets_, input_std_, x, PenaltyOptions{}, &value,
                             &gradient));
}

TEST(InitialHyperparametersTest, FollowsPilcoTrain) {
  RowMatrix inputs(4, 3);
  inputs << 1, 5, 2,  //
      2, 5, 4,        //
      3, 5, 6,        //
      4, 5, 8;
  RowMatrix targets(4, 2);
  targets << 0, 1, 0, -1, 0, 1, 0, -1;
  const GpHyperparameters hyp = InitialHyperparameters(inputs, targets);
  ASSERT_EQ(hyp.num_outputs(), 2);
  ASSERT_EQ(hyp.num_inputs(), 3);
  // std([1 2 3 4]) with N-1 is sqrt(5/3); the constant column falls back to 1.
  for (int a = 0; a < 2; ++a) {
    EXPECT_NEAR(hyp.log_lengthscales(a, 0), std::log(std::sqrt(5.0 / 3.0)), 1e-14);
    EXPECT_EQ(hyp.log_lengthscales(a, 1), 0.0);
    EXPECT_NEAR(hyp.log_lengthscales(a, 2), std::log(2 * std::sqrt(5.0 / 3.0)), 1e-14);
  }
  // targets: a zero column (std 0 -> 1) and +-1 (std sqrt(4/3)).
  EXPECT_EQ(hyp.log_signal_std(0), 0.0);
  EXPECT_NEAR(hyp.log_noise_std(0), std::log(0.1), 1e-14);
  EXPECT_NEAR(hyp.log_signal_std(1), std::log(std::sqrt(4.0 / 3.0)), 1e-14);
  EXPECT_NEAR(hyp.log_noise_std(1), std::log(std::sqrt(4.0 / 3.0) / 10), 1e-14);
}

double TotalStartLoss(const Data& data, const GpHyperparameters& hyp, int a) {
  double value = 0;
  EXPECT_TRUE(PenalisedNlml(data.inputs, data.targets.col(a), ReferenceStd(data.inputs),
                            hyp.Packed(a), PenaltyOptions{}, &value, nullptr));
  return value;
}

TEST(TrainHyperparametersTest, ImprovesLossAndRecoversNoiseLevel) {
  const double true_noise[2] = {0.05, 0.2};
  const Data data = MakeData(150, true_noise[0], true_noise[1], 3);
  GpHyperparameters hyp = InitialHyperparameters(data.inputs, data.targets);
  const double start_loss[2] = {TotalStartLoss(data, hyp, 0), TotalStartLoss(data, hyp, 1)};

  absl::StatusOr<TrainingSummary> summary =
      TrainHyperparameters(data.inputs, data.targets, TrainingOptions{}, &hyp);
  TG_ASSERT_OK(summary.status());
  // A well-posed problem converges without any failure.
  EXPECT_EQ(summary->line_search_failures, 0) << summary->BriefReport();
  EXPECT_EQ(summary->non_finite_evaluations, 0) << summary->BriefReport();
  ASSERT_EQ(summary->final_loss.size(), 2u);
  ASSERT_EQ(summary->iterations.size(), 2u);
  for (int a = 0; a < 2; ++a) {
    SCOPED_TRACE(a);
    // A well-specified model with 150 points: the loss drops by far more
    // than round-off, and the noise std comes back within a factor 1.3. The
    // sampling spread of a noise std estimate at N = 150 is ~6%, and this
    // seed's realised noise stds are 0.052 and 0.168 (estimates: 0.051, 0.171).
    EXPECT_LT(summary->final_loss[a], start_loss[a] - 10.0);
    const double sn = std::exp(hyp.log_noise_std(a));
    EXPECT_GT(sn, true_noise[a] / 1.3);
    EXPECT_LT(sn, true_noise[a] * 1.3);
    EXPECT_GT(summary->iterations[a], 0);
    EXPECT_LE(summary->iterations[a], TrainingOptions{}.max_iterations);
    // The summary's loss is the loss at the returned point.
    EXPECT_EQ(summary->final_loss[a], TotalStartLoss(data, hyp, a));
  }
  EXPECT_TRUE(hyp.log_lengthscales.allFinite());
  TG_ASSERT_OK(GpModel::Create(data.inputs, data.targets, hyp).status());

  // Warm start from the optimum: no worse, and far fewer iterations.
  GpHyperparameters again = hyp;
  absl::StatusOr<TrainingSummary> second =
      TrainHyperparameters(data.inputs, data.targets, TrainingOptions{}, &again);
  TG_ASSERT_OK(second.status());
  for (int a = 0; a < 2; ++a) {
    EXPECT_LE(second->final_loss[a], summary->final_loss[a]);
    EXPECT_LT(second->iterations[a], summary->iterations[a]);
  }
  EXPECT_THAT(summary->BriefReport(), HasSubstr("2 outputs"));
  EXPECT_THAT(summary->BriefReport(), HasSubstr("line-search failures"));
}

TEST(TrainHyperparametersTest, ZeroIterationsReturnsTheStartPoint) {
  const Data data = MakeData(40, 0.1, 0.1, 4);
  const GpHyperparameters start = InitialHyperparameters(data.inputs, data.targets);
  GpHyperparameters hyp = start;
  TrainingOptions options;
  options.max_iterations = 0;
  absl::StatusOr<TrainingSummary> summary =
      TrainHyperparameters(data.inputs, data.targets, options, &hyp);
  TG_ASSERT_OK(summary.status());
  EXPECT_EQ(hyp.Packed(0), start.Packed(0));
  EXPECT_EQ(hyp.Packed(1), start.Packed(1));
  EXPECT_EQ(summary->iterations[0], 0);
  EXPECT_EQ(summary->final_loss[0], TotalStartLoss(data, start, 0));
}

TEST(TrainHyperparametersTest, DegenerateDataDoesNotCrash) {
  // Each input twice, one constant input column, and (output 1) all-zero
  // targets, whose NLML is unbounded below as sf, sn -> 0 together.
  const Data base = MakeData(20, 0.05, 0.0, 5);
  RowMatrix inputs(40, 3);
  RowMatrix targets(40, 2);
  for (int i = 0; i < 20; ++i) {
    for (int copy = 0; copy < 2; ++copy) {
      inputs.row(2 * i + copy) << base.inputs(i, 0), base.inputs(i, 1), 3.0;
      targets.row(2 * i + copy) << base.targets(i, 0), 0.0;
    }
  }
  GpHyperparameters hyp = InitialHyperparameters(inputs, targets);
  absl::StatusOr<TrainingSummary> summary =
      TrainHyperparameters(inputs, targets, TrainingOptions{}, &hyp);
  if (summary.ok()) {
    EXPECT_TRUE(hyp.log_lengthscales.allFinite());
    EXPECT_TRUE(hyp.log_signal_std.allFinite());
    EXPECT_TRUE(hyp.log_noise_std.allFinite());
    EXPECT_TRUE(std::isfinite(summary->final_loss[0]));
    EXPECT_TRUE(std::isfinite(summary->final_loss[1]));
    // Output 1's loss decreases without bound towards sf, sn -> 0, so the
    // optimiser must have run into K that are not positive definite.
    EXPECT_GT(summary->non_finite_evaluations, 0);
    // The result must be usable: the model builds (jitter allowed) and predicts.
    absl::StatusOr<GpModel> model = GpModel::Create(inputs, targets, hyp);
    TG_ASSERT_OK(model.status());
    RowMatrix mean, var;
    model->Predict(inputs.topRows(5), PredictOptions{}, &mean, &var, nullptr, nullptr);
    EXPECT_TRUE(mean.allFinite() && var.allFinite());
  } else {
    EXPECT_EQ(summary.status().code(), absl::StatusCode::kFailedPrecondition)
        << summary.status();
  }
}

TEST(TrainHyperparametersTest, NonFiniteStartIsAFailedPreconditionAndChangesNothing) {
  const Data data = MakeData(20, 0.1, 0.1, 6);
  GpHyperparameters hyp = InitialHyperparameters(data.inputs, data.targets);
  hyp.log_signal_std(1) = -400.0;  // K_1 = 0 after underflow
  hyp.log_noise_std(1) = -400.0;
  const GpHyperparameters before = hyp;
  absl::StatusOr<TrainingSummary> summary =
      TrainHyperparameters(data.inputs, data.targets, TrainingOptions{}, &hyp);
  EXPECT_EQ(summary.status().code(), absl::StatusCode::kFailedPrecondition);
  EXPECT_THAT(summary.status().message(), HasSubstr("output 1"));
  EXPECT_EQ(hyp.log_lengthscales, before.log_lengthscales);
  EXPECT_EQ(hyp.log_signal_std, before.log_signal_std);
  EXPECT_EQ(hyp.log_noise_std, before.log_noise_std);
}

TEST(TrainHyperparametersTest, InvalidArgumentsNameTheField) {
  const Data data = MakeData(10, 0.1, 0.1, 7);
  const GpHyperparameters hyp = InitialHyperparameters(data.inputs, data.targets);
  auto expect_error = [&](const RowMatrix& inputs, const RowMatrix& targets,
                          GpHyperparameters h, const TrainingOptions& options,
                          const std::string& field) {
    const absl::StatusOr<TrainingSummary> s = TrainHyperparameters(inputs, targets, options, &h);
    EXPECT_EQ(s.status().code(), absl::StatusCode::kInvalidArgument) << field;
    EXPECT_THAT(s.status().message(), HasSubstr(field));
  };
  const TrainingOptions ok_options;
  expect_error(data.inputs.topRows(9), data.targets, hyp, ok_options, "targets has 10 rows");
  expect_error(data.inputs.leftCols(1), data.targets, hyp, ok_options, "log_lengthscales");
  RowMatrix nan_inputs = data.inputs;
  nan_inputs(2, 1) = std::numeric_limits<double>::quiet_NaN();
  expect_error(nan_inputs, data.targets, hyp, ok_options, "inputs(2, 1)");
  RowMatrix nan_targets = data.targets;
  nan_targets(4, 0) = std::numeric_limits<double>::quiet_NaN();
  expect_error(data.inputs, nan_targets, hyp, ok_options, "targets(4, 0)");
  GpHyperparameters bad = hyp;
  bad.log_noise_std(0) = std::numeric_limits<double>::infinity();
  expect_error(data.inputs, data.targets, bad, ok_options, "log_noise_std");
  TrainingOptions bad_options;
  bad_options.penalty.signal_to_noise = 1.0;
  expect_error(data.inputs, data.targets, hyp, bad_options, "signal_to_noise");
}

// The L-BFGS driver's failure handling, on functions where the answer is known.
bool Rosenbrock(const Vector& x, double* value, Vector* gradient) {
  *value = 100 * std::pow(x(1) - x(0) * x(0), 2) + std::pow(1 - x(0), 2);
  if (gradient != nullptr) {
    gradient->resize(2);
    (*gradient)(0) = -400 * x(0) * (x(1) - x(0) * x(0)) - 2 * (1 - x(0));
    (*gradient)(1) = 200 * (x(1) - x(0) * x(0));
  }
  return true;
}

TEST(MinimizeLbfgsTest, FindsTheRosenbrockMinimum) {
  internal::MinimizeResult result;
  ASSERT_TRUE(internal::MinimizeLbfgs(Rosenbrock, Vector::Constant(2, -1.2), 300, &result));
  EXPECT_NEAR(result.x(0), 1.0, 1e-4);
  EXPECT_NEAR(result.x(1), 1.0, 1e-4);
  EXPECT_LT(result.value, 1e-8);
  EXPECT_GT(result.iterations, 5);
  EXPECT_EQ(result.non_finite_evaluations, 0);
}

TEST(MinimizeLbfgsTest, FailedEvaluationsAreCountedAndNeverReturned) {
  // Rosenbrock that fails (like a Cholesky of a non-PD K) beyond x0 = 1.05 or
  // x1 = 1.2, i.e. just past the minimum (1, 1), where L-BFGS overshoots.
  const internal::ObjectiveFunction walled = [](const Vector& x, double* value,
                                                Vector* gradient) {
    if (x(0) > 1.05 || x(1) > 1.2) return false;
    return Rosenbrock(x, value, gradient);
  };
  Vector start(2);
  start << -1.2, 1.0;
  internal::MinimizeResult result;
  ASSERT_TRUE(internal::MinimizeLbfgs(walled, start, 300, &result));
  EXPECT_GT(result.non_finite_evaluations, 0);
  EXPECT_NEAR(result.x(0), 1.0, 1e-4);
  EXPECT_NEAR(result.x(1), 1.0, 1e-4);
  double value = 0;
  ASSERT_TRUE(walled(result.x, &value, nullptr));
  EXPECT_EQ(result.value, value);
}

// |x - c|^2 + 0.5 (x0 - c0)^4 whose gradient has the wrong sign wherever the
// value is below 1: L-BFGS makes progress until it gets there, then every
// line search fails.
bool WrongGradientNearMinimum(const Vector& x, double* value, Vector* gradient) {
  Vector c(3);
  c << 1.0, -2.0, 0.5;
  *value = (x - c).squaredNorm() + 0.5 * std::pow(x(0) - c(0), 4);
  if (gradient != nullptr) {
    *gradient = 2 * (x - c);
    (*gradient)(0) += 2 * std::pow(x(0) - c(0), 3);
    if (*value < 1) *gradient = -*gradient;
  }
  return true;
}

TEST(MinimizeLbfgsTest, LineSearchFailureKeepsBestPointAndRestartsOnce) {
  internal::MinimizeResult result;
  const Vector start = Vector::Constant(3, 3.0);
  ASSERT_TRUE(internal::MinimizeLbfgs(WrongGradientNearMinimum, start, 300, &result));
  // The first failure follows progress, so L-BFGS restarts from the best
  // point; the restart fails without progress and ends the run.
  EXPECT_EQ(result.line_search_failures, 2);
  EXPECT_LT(result.value, 1.0);
  double value = 0;
  ASSERT_TRUE(WrongGradientNearMinimum(result.x, &value, nullptr));
  EXPECT_EQ(result.value, value);

  // Wrong everywhere: the very first line search fails, the start is kept.
  const internal::ObjectiveFunction always_wrong = [](const Vector& x, double* value,
                                                      Vector* gradient) {
    *value = x.squaredNorm();
    if (gradient != nullptr) *gradient = -2 * x;
    return true;
  };
  ASSERT_TRUE(internal::MinimizeLbfgs(always_wrong, start, 300, &result));
  EXPECT_EQ(result.line_search_failures, 1);
  EXPECT_EQ(result.iterations, 0);
  EXPECT_EQ(result.x, start);
}

TEST(MinimizeLbfgsTest, ZeroIterationsAndFailingStart) {
  internal::MinimizeResult result;
  Vector start(2);
  start << 0.5, 0.5;
  ASSERT_TRUE(internal::MinimizeLbfgs(Rosenbrock, start, 0, &result));
  EXPECT_EQ(result.x, start);
  EXPECT_EQ(result.iterations, 0);
  EXPECT_EQ(result.evaluations, 1);
  const internal::ObjectiveFunction always_fails = [](const Vector&, double*, Vector*) {
    return false;
  };
  EXPECT_FALSE(internal::MinimizeLbfgs(always_fails, start, 300, &result));
  EXPECT_EQ(result.non_finite_evaluations, 1);
}

}  // namespace training_test
}  // namespace totalgrad::gp
