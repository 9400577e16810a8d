#include "core/gp/gp.h"

#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <Eigen/Cholesky>
#include <algorithm>
#include <cmath>
#include <cstdint>
#include <functional>
#include <limits>
#include <thread>
#include <vector>

#include "core/common/rng.h"
#include "core/diff/gradient_checker.h"
#include "core/gp/se_kernel.h"
#include "tests/core/gp/predict_check.h"
#include "tests/testutil/testutil.h"

namespace totalgrad::gp {
namespace gp_test {

using ::testing::HasSubstr;
using totalgrad::testing::MatricesNear;

using Problem = testing::TwoOutputProblem;
using testing::UniformMatrix;

Problem MakeProblem(int n, uint64_t seed) {
  return testing::MakeTwoOutputProblem(n, seed, 0.1, 0.2, testing::ShortLengthscales());
}

// Queries: half near training inputs (where the variance is small and most
// sensitive), half spread out.
RowMatrix MakeQueries(const Problem& problem, int p, uint64_t seed) {
  Rng rng(seed, Stream::kEvaluation);
  RowMatrix z = UniformMatrix(&rng, p, 3, -2.5, 2.5);
  for (int i = 0; i < p; i += 2) {
    for (int m = 0; m < 3; ++m) z(i, m) = problem.inputs(i, m) + 0.05 * rng.Normal();
  }
  return z;
}

using ::totalgrad::gp::testing::BlockJacobian;
using ::totalgrad::gp::testing::PredictFunction;

// Central differences with step 1e-6 have truncation error ~1e-12 here; the
// round-off of the variance (sf^2 - k^T K^-1 k, with |K^-1| ~ 1/sn^2 = 100)
// divided by the step stays below ~1e-8 (measured: 4e-9). Real mistakes (a
// missing factor, a wrong sign, a mixed-up length-scale) give errors of order
// 1e-3 or more.
diff::CheckOptions JacobianCheckOptions() {
  diff::CheckOptions options;
  options.relative_step = 1e-6;
  options.relative_tolerance = 1e-6;
  options.absolute_tolerance = 1e-7;
  return options;
}

TEST(GpModelTest, JacobiansMatchFiniteDifferences) {
  const Problem problem = MakeProblem(40, 1);
  absl::StatusOr<GpModel> model = GpModel::Create(problem.inputs, problem.targets, problem.hyp);
  TG_ASSERT_OK(model.status());
  const int p = 6;
  const RowMatrix z = MakeQueries(problem, p, 2);
  PredictOptions options;
  options.noise_variance_multiplier = 25.0;  // GTP+sigma_n: exercises the mult term
  RowMatrix mean, var, dmean, dvar;
  model->Predict(z, options, &mean, &var, &dmean, &dvar);
  const Vector x = Eigen::Map<const Vector>(z.data(), z.size());

  const diff::CheckResult mean_check =
      diff::CheckJacobian(PredictFunction(*model, options, p, false), x,
                          BlockJacobian(dmean, 2, 3), JacobianCheckOptions());
  EXPECT_TRUE(mean_check.ok) << mean_check.log;
  const diff::CheckResult var_check =
      diff::CheckJacobian(PredictFunction(*model, options, p, true), x,
                          BlockJacobian(dvar, 2, 3), JacobianCheckOptions());
  EXPECT_TRUE(var_check.ok) << var_check.log;
  // The check must be about something: the derivatives are not all tiny.
  EXPECT_GT(dmean.cwiseAbs().maxCoeff(), 0.1);
  EXPECT_GT(dvar.cwiseAbs().maxCoeff(), 0.01);
}

TEST(GpModelTest, WrongJacobianFailsTheCheck) {
  const Problem problem = MakeProblem(40, 1);
  absl::StatusOr<GpModel> model = GpModel::Create(problem.inputs, problem.targets, problem.hyp);
  TG_ASSERT_OK(model.status());
  const int p = 6;
  const RowMatrix z = MakeQueries(problem, p, 2);
  const PredictOptions options{25.0};
  ::totalgrad::gp::testing::ExpectTypicalSlipsFailTheCheck(*model, z, options,
                                                          JacobianCheckOptions());
}

TEST(GpModelTest, RecoversSmoothFunctionAndItsUncertainty) {
  // y = sin(z1) + 0.5 z2^2 + N(0, 0.01^2) on [-2, 2]^2.
  const int n = 200;
  Rng rng(3, Stream::kStudy);
  const RowMatrix x = UniformMatrix(&rng, n, 2, -2.0, 2.0);
  RowMatrix y(n, 1);
  for (int i = 0; i < n; ++i) y(i, 0) = std::sin(x(i, 0)) + 0.5 * x(i, 1) * x(i, 1) + 0.01 * rng.Normal();
  GpHyperparameters hyp;
  hyp.log_lengthscales = RowMatrix::Constant(1, 2, std::log(1.2));
  hyp.log_signal_std = Vector::Constant(1, std::log(1.5));
  hyp.log_noise_std = Vector::Constant(1, std::log(0.01));
  absl::StatusOr<GpModel> model = GpModel::Create(x, y, hyp);
  TG_ASSERT_OK(model.status());
  EXPECT_EQ(model->jitter(0), 0.0);

  // Interior grid: the posterior mean must reproduce the function.
  RowMatrix grid(49, 2);
  for (int i = 0; i < 7; ++i)
    for (int j = 0; j < 7; ++j) grid.row(i * 7 + j) << -1.5 + 0.5 * i, -1.5 + 0.5 * j;
  RowMatrix mean, var;
  model->Predict(grid, PredictOptions{}, &mean, &var, nullptr, nullptr);
  double max_error = 0;
  for (int i = 0; i < 49; ++i) {
    const double truth = std::sin(grid(i, 0)) + 0.5 * grid(i, 1) * grid(i, 1);
    max_error = std::max(max_error, std::abs(mean(i, 0) - truth));
  }
  EXPECT_LT(max_error, 0.02);
  // Inside the data the latent uncertainty is small: total variance close to
  // sn^2 = 1e-4, far below the prior sf^2 + sn^2 = 2.25.
  EXPECT_LT(var.maxCoeff(), 1e-3);
  EXPECT_GT(var.minCoeff(), 0.9e-4);

  // Far from the data the prior comes back: mean 0, variance sf^2 + sn^2 (or
  // sf^2 + mult sn^2).
  RowMatrix far(2, 2);
  far << 40.0, -40.0, -35.0, 60.0;
  model->Predict(far, PredictOptions{}, &mean, &var, nullptr, nullptr);
  EXPECT_NEAR(mean(0, 0), 0.0, 1e-12);
  EXPECT_NEAR(mean(1, 0), 0.0, 1e-12);
  EXPECT_NEAR(var(0, 0), 1.5 * 1.5 + 0.01 * 0.01, 1e-12);
  EXPECT_NEAR(var(1, 0), 1.5 * 1.5 + 0.01 * 0.01, 1e-12);
  model->Predict(far, PredictOptions{25.0}, &mean, &var, nullptr, nullptr);
  EXPECT_NEAR(var(0, 0), 1.5 * 1.5 + 25 * 0.01 * 0.01, 1e-12);
  model->Predict(far, PredictOptions{0.0}, &mean, &var, nullptr, nullptr);
  EXPECT_NEAR(var(0, 0), 1.5 * 1.5, 1e-12);
}

TEST(GpModelTest, BatchPredictionEqualsSingleRowPredictions) {
  const Problem problem = MakeProblem(60, 4);
  absl::StatusOr<GpModel> model = GpModel::Create(problem.inputs, problem.targets, problem.hyp);
  TG_ASSERT_OK(model.status());
  const int p = 13;
  const RowMatrix z = MakeQueries(problem, p, 5);
  const PredictOptions options{25.0};
  RowMatrix mean, var, dmean, dvar;
  model->Predict(z, options, &mean, &var, &dmean, &dvar);
  ASSERT_EQ(mean.rows(), p);
  ASSERT_EQ(dvar.cols(), 2 * 3);
  for (int i = 0; i < p; ++i) {
    RowMatrix m1, v1, dm1, dv1;
    model->Predict(z.row(i), options, &m1, &v1, &dm1, &dv1);
    // One row goes through BLAS gemv, many through gemm: they sum in a
    // different order. The variance sf^2 - k^T K^-1 k is a difference of O(1)
    // numbers whose terms involve K^-1 entries up to ~1/sn^2 = 100, so the
    // order can move it by ~N eps |K^-1| ~ 1e-12; any real mistake (rows
    // mixed up, a particle seeing another's data) is O(1e-3) or more.
    EXPECT_TRUE(MatricesNear(m1, mean.row(i), 1e-11, 1e-10)) << "row " << i;
    EXPECT_TRUE(MatricesNear(v1, var.row(i), 1e-11, 1e-10)) << "row " << i;
    EXPECT_TRUE(MatricesNear(dm1, dmean.row(i), 1e-11, 1e-10)) << "row " << i;
    EXPECT_TRUE(MatricesNear(dv1, dvar.row(i), 1e-11, 1e-10)) << "row " << i;
  }
}

TEST(GpModelTest, JacobianRequestsDoNotChangeValues) {
  const Problem problem = MakeProblem(50, 6);
  absl::StatusOr<GpModel> model = GpModel::Create(problem.inputs, problem.targets, problem.hyp);
  TG_ASSERT_OK(model.status());
  const RowMatrix z = MakeQueries(problem, 9, 7);
  RowMatrix mean, var, dmean, dvar, mean2, var2, mean3;
  model->Predict(z, PredictOptions{}, &mean, &var, &dmean, &dvar);
  model->Predict(z, PredictOptions{}, &mean2, &var2, nullptr, nullptr);
  model->Predict(z, PredictOptions{}, &mean3, nullptr, nullptr, nullptr);  // mean only
  // Bitwise: the same arithmetic runs whatever is requested.
  EXPECT_EQ(mean, mean2);
  EXPECT_EQ(var, var2);
  EXPECT_EQ(mean, mean3);
}

TEST(GpModelTest, ConcurrentPredictionsMatchSerialOnes) {
  // Predict keeps its scratch space per thread; two threads with different
  // batch sizes must not disturb each other.
  const Problem problem = MakeProblem(80, 16);
  absl::StatusOr<GpModel> model = GpModel::Create(problem.inputs, problem.targets, problem.hyp);
  TG_ASSERT_OK(model.status());
  const RowMatrix z1 = MakeQueries(problem, 37, 17), z2 = MakeQueries(problem, 5, 18);
  RowMatrix mean1, var1, dmean1, dvar1, mean2, var2, dmean2, dvar2;
  model->Predict(z1, PredictOptions{}, &mean1, &var1, &dmean1, &dvar1);
  model->Predict(z2, PredictOptions{}, &mean2, &var2, &dmean2, &dvar2);
  bool same1 = true, same2 = true;
  auto run = [&](const RowMatrix& z, const RowMatrix& mean, const RowMatrix& var,
                 const RowMatrix& dmean, const RowMatrix& dvar, bool* same) {
    RowMatrix m, v, dm, dv;
    for (int rep = 0; rep < 500; ++rep) {
      model->Predict(z, PredictOptions{}, &m, &v, &dm, &dv);
      *same = *same && m == mean && v == var && dm == dmean && dv == dvar;
    }
  };
  std::thread t1(run, std::cref(z1), std::cref(mean1), std::cref(var1), std::cref(dmean1),
                 std::cref(dvar1), &same1);
  std::thread t2(run, std::cref(z2), std::cref(mean2), std::cref(var2), std::cref(dmean2),
                 std::cref(dvar2), &same2);
  t1.join();
  t2.join();
  EXPECT_TRUE(same1);
  EXPECT_TRUE(same2);
}

TEST(GpModelTest, EmptyAndNonFiniteQueries) {
  const Problem problem = MakeProblem(20, 19);
  absl::StatusOr<GpModel> model = GpModel::Create(problem.inputs, problem.targets, problem.hyp);
  TG_ASSERT_OK(model.status());
  RowMatrix mean, var, dmean, dvar;
  model->Predict(RowMatrix(0, 3), PredictOptions{}, &mean, &var, &dmean, &dvar);
  EXPECT_EQ(mean.rows(), 0);
  EXPECT_EQ(mean.cols(), 2);
  EXPECT_EQ(dvar.cols(), 6);
  // A NaN query must not come back as a plausible finite prediction.
  RowMatrix z = MakeQueries(problem, 3, 20);
  z(1, 2) = std::numeric_limits<double>::quiet_NaN();
  model->Predict(z, PredictOptions{}, &mean, &var, nullptr, nullptr);
  EXPECT_TRUE(mean.row(0).allFinite() && var.row(0).allFinite());
  EXPECT_TRUE(mean.row(1).array().isNaN().all()) << mean.row(1);
  EXPECT_TRUE(var.row(1).array().isNaN().all()) << var.row(1);
}

TEST(GpModelTest, VarianceFloorZeroesTheJacobianRow) {
  const Problem problem = MakeProblem(30, 8);
  absl::StatusOr<GpModel> model = GpModel::Create(problem.inputs, problem.targets, problem.hyp);
  TG_ASSERT_OK(model.status());
  const RowMatrix z = MakeQueries(problem, 4, 9);
  // An unphysical negative multiplier drives sf^2 - k^T K^-1 k + mult sn^2
  // below zero everywhere, so the floor binds for every row.
  RowMatrix mean, var, dmean, dvar;
  model->Predict(z, PredictOptions{-1e3}, &mean, &var, &dmean, &dvar);
  EXPECT_TRUE((var.array() == 1e-12).all()) << var;
  EXPECT_TRUE((dvar.array() == 0.0).all()) << dvar;
  EXPECT_GT(dmean.cwiseAbs().maxCoeff(), 0.0);
}

TEST(GpModelTest, DuplicateInputsWithTinyNoiseUseJitter) {
  // Ten distinct inputs, each twice: with tiny noise K is singular to round-off.
  Rng rng(10, Stream::kStudy);
  const RowMatrix unique = UniformMatrix(&rng, 10, 2, -2.0, 2.0);
  RowMatrix x(20, 2), y(20, 1);
  for (int i = 0; i < 10; ++i) {
    x.row(2 * i) = unique.row(i);
    x.row(2 * i + 1) = unique.row(i);
    y(2 * i, 0) = y(2 * i + 1, 0) = std::sin(unique(i, 0)) * unique(i, 1);
  }
  GpHyperparameters hyp;
  hyp.log_lengthscales = RowMatrix::Constant(1, 2, std::log(0.8));
  hyp.log_signal_std = Vector::Constant(1, 0.0);
  // The second copy's Cholesky pivot is 2 sn^2 (+ round-off ~eps sf^2).
  // sn = 1e-9: the pivot is round-off and LLT itself fails. sn = 3e-8: the
  // pivot 1.8e-15 is positive, LLT "succeeds", but it is below N eps sf^2 =
  // 4.4e-15 and K^-1 (~1/pivot) would be garbage.
  for (const double sn : {1e-9, 3e-8}) {
    SCOPED_TRACE(sn);
    hyp.log_noise_std = Vector::Constant(1, std::log(sn));
    absl::StatusOr<GpModel> model = GpModel::Create(x, y, hyp);
    TG_ASSERT_OK(model.status());
    EXPECT_GT(model->jitter(0), 0.0);
    EXPECT_LE(model->jitter(0), 1e-2);
    // Bounded by 1 / (smallest eigenvalue >= jitter = 1e-8 sf^2).
    EXPECT_LT(model->k_inverse(0).cwiseAbs().maxCoeff(), 1e9);

    // With jitter the GP still interpolates its (consistent) duplicated data.
    RowMatrix mean, var, dmean, dvar;
    model->Predict(unique, PredictOptions{}, &mean, &var, &dmean, &dvar);
    for (int i = 0; i < 10; ++i) EXPECT_NEAR(mean(i, 0), y(2 * i, 0), 1e-4) << i;
    EXPECT_TRUE(var.allFinite() && dmean.allFinite() && dvar.allFinite());
    EXPECT_LT(var.maxCoeff(), 1e-4);
  }

  // The same data with a sensible noise level needs no jitter.
  hyp.log_noise_std(0) = std::log(0.1);
  absl::StatusOr<GpModel> noisy = GpModel::Create(x, y, hyp);
  TG_ASSERT_OK(noisy.status());
  EXPECT_EQ(noisy->jitter(0), 0.0);
}

TEST(GpModelTest, FailsWhenJitterCannotHelp) {
  // exp(2 * -400) underflows to 0: K is the zero matrix and the jitter ladder,
  // relative to sf^2 = 0, adds nothing.
  const Problem problem = MakeProblem(10, 11);
  GpHyperparameters hyp = problem.hyp;
  hyp.log_signal_std.setConstant(-400.0);
  hyp.log_noise_std.setConstant(-400.0);
  const absl::StatusOr<GpModel> model = GpModel::Create(problem.inputs, problem.targets, hyp);
  EXPECT_EQ(model.status().code(), absl::StatusCode::kFailedPrecondition);
  EXPECT_THAT(model.status().message(), HasSubstr("output 0"));
}

TEST(GpModelTest, InvalidArgumentsNameTheField) {
  const Problem problem = MakeProblem(10, 12);
  auto expect_error = [](const absl::StatusOr<GpModel>& model, const std::string& field) {
    EXPECT_EQ(model.status().code(), absl::StatusCode::kInvalidArgument) << field;
    EXPECT_THAT(model.status().message(), HasSubstr(field));
  };
  expect_error(GpModel::Create(problem.inputs.topRows(9), problem.targets, problem.hyp),
               "targets has 10 rows but inputs has 9");
  expect_error(GpModel::Create(problem.inputs.leftCols(2), problem.targets, problem.hyp),
               "log_lengthscales");
  expect_error(GpModel::Create(problem.inputs, problem.targets.leftCols(1), problem.hyp),
               "log_lengthscales");
  expect_error(GpModel::Create(RowMatrix(0, 3), RowMatrix(0, 2), problem.hyp), "N == 0");
  GpHyperparameters short_noise = problem.hyp;
  short_noise.log_noise_std.resize(1);
  expect_error(GpModel::Create(problem.inputs, problem.targets, short_noise), "log_noise_std");

  RowMatrix bad_inputs = problem.inputs;
  bad_inputs(3, 1) = std::numeric_limits<double>::quiet_NaN();
  expect_error(GpModel::Create(bad_inputs, problem.targets, problem.hyp), "inputs(3, 1)");
  RowMatrix bad_targets = problem.targets;
  bad_targets(7, 0) = std::numeric_limits<double>::infinity();
  expect_error(GpModel::Create(problem.inputs, bad_targets, problem.hyp), "targets(7, 0)");
  GpHyperparameters bad_hyp = problem.hyp;
  bad_hyp.log_signal_std(1) = std::numeric_limits<double>::quiet_NaN();
  expect_error(GpModel::Create(problem.inputs, problem.targets, bad_hyp), "log_signal_std");
  bad_hyp = problem.hyp;
  bad_hyp.log_lengthscales(1, 2) = -1000.0;  // l underflows to 0
  expect_error(GpModel::Create(problem.inputs, problem.targets, bad_hyp), "log_lengthscales");
}

TEST(GpModelTest, CachedQuantitiesAreConsistent) {
  const Problem problem = MakeProblem(25, 13);
  absl::StatusOr<GpModel> model = GpModel::Create(problem.inputs, problem.targets, problem.hyp);
  TG_ASSERT_OK(model.status());
  EXPECT_EQ(model->num_data(), 25);
  EXPECT_EQ(model->num_inputs(), 3);
  EXPECT_EQ(model->num_outputs(), 2);
  EXPECT_EQ(model->inputs(), problem.inputs);
  EXPECT_EQ(model->targets(), problem.targets);
  for (int a = 0; a < 2; ++a) {
    // Rebuild K_a naively and check K^-1 and beta against it.
    const Vector l = problem.hyp.log_lengthscales.row(a).array().exp().transpose();
    const double sf2 = std::exp(2 * problem.hyp.log_signal_std(a));
    const double sn2 = std::exp(2 * problem.hyp.log_noise_std(a));
    Matrix k(25, 25);
    for (int i = 0; i < 25; ++i)
      for (int j = 0; j < 25; ++j) {
        const Vector d = (problem.inputs.row(i) - problem.inputs.row(j)).transpose();
        k(i, j) = sf2 * std::exp(-0.5 * d.cwiseQuotient(l).squaredNorm()) + (i == j ? sn2 : 0);
      }
    EXPECT_TRUE(MatricesNear(k * model->k_inverse(a), Matrix::Identity(25, 25), 1e-9, 0));
    EXPECT_TRUE(MatricesNear(k * model->beta(a), problem.targets.col(a), 1e-9, 1e-9));
    EXPECT_EQ(model->k_inverse(a), model->k_inverse(a).transpose());

    // Predict against the textbook formulas evaluated one query at a time.
    const RowMatrix z = MakeQueries(problem, 5, 15);
    RowMatrix mean, var;
    model->Predict(z, PredictOptions{25.0}, &mean, &var, nullptr, nullptr);
    const Eigen::LDLT<Matrix> ldlt(k);
    for (int i = 0; i < 5; ++i) {
      Vector ks(25);
      for (int j = 0; j < 25; ++j) {
        const Vector d = (z.row(i) - problem.inputs.row(j)).transpose();
        ks(j) = sf2 * std::exp(-0.5 * d.cwiseQuotient(l).squaredNorm());
      }
      EXPECT_NEAR(mean(i, a), ks.dot(ldlt.solve(problem.targets.col(a))), 1e-10);
      EXPECT_NEAR(var(i, a), sf2 - ks.dot(ldlt.solve(ks)) + 25 * sn2, 1e-10);
    }
  }
}

TEST(GpHyperparametersTest, PackedRoundTrip) {
  GpHyperparameters hyp = MakeProblem(5, 14).hyp;
  const Vector packed = hyp.Packed(1);
  ASSERT_EQ(packed.size(), 5);
  EXPECT_EQ(packed(0), hyp.log_lengthscales(1, 0));
  EXPECT_EQ(packed(2), hyp.log_lengthscales(1, 2));
  EXPECT_EQ(packed(3), hyp.log_signal_std(1));
  EXPECT_EQ(packed(4), hyp.log_noise_std(1));
  Vector changed = packed.array() + 1.0;
  hyp.SetPacked(1, changed);
  EXPECT_EQ(hyp.Packed(1), changed);
  EXPECT_EQ(hyp.Packed(0), MakeProblem(5, 14).hyp.Packed(0));  // other output untouched
}

}  // namespace gp_test
}  // namespace totalgrad::gp
