// FitcModel::Predict, the sparse GP's batched point prediction used by the
// particle rollouts with gp_inducing (core/gp/fitc.h): Jacobians against
// finite differences (and a wrong one that the checker must reject), agreement
// with the full GP when the inducing inputs are the training inputs, and the
// GpModel::Predict contract (batch = single rows, Jacobian requests and
// mean-only calls do not change values), and FitFitcModel.
#include "core/gp/fitc.h"

#include <gtest/gtest.h>

#include <cmath>

#include "core/common/rng.h"
#include "core/diff/gradient_checker.h"
#include "core/gp/gp.h"
#include "tests/core/gp/predict_check.h"
#include "tests/testutil/testutil.h"

namespace totalgrad::gp {
namespace fitc_predict_test {

using totalgrad::testing::MatricesNear;

using Problem = testing::TwoOutputProblem;
using testing::UniformMatrix;

Problem MakeProblem(int n, uint64_t seed, double noise0 = 0.1, double noise1 = 0.2) {
  return testing::MakeTwoOutputProblem(n, seed, noise0, noise1, testing::ShortLengthscales());
}

// Half the queries near training inputs, half spread out.
RowMatrix MakeQueries(const Problem& problem, int p, uint64_t seed) {
  Rng rng(seed, Stream::kEvaluation);
  RowMatrix z = UniformMatrix(&rng, p, 3, -2.5, 2.5);
  for (int i = 0; i < p; i += 2)
    for (int m = 0; m < 3; ++m) z(i, m) = problem.inputs(i, m) + 0.05 * rng.Normal();
  return z;
}

absl::StatusOr<FitcModel> SparseModel(const Problem& problem, int m, uint64_t seed) {
  Rng rng(seed, Stream::kGpInit);
  return FitcModel::Create(problem.inputs, problem.targets, problem.hyp,
                           RandomSubsetOfInputs(problem.inputs, m, &rng));
}

using ::totalgrad::gp::testing::BlockJacobian;
using ::totalgrad::gp::testing::PredictFunction;

// As for the full GP (gp_test.cc): central differences with step 1e-6 have
// truncation error ~1e-12; the variance sf^2 - k^T Vw k has round-off of
// ~eps |Vw| |k|^2 with |Vw| up to ~1/sn^2 = 100, i.e. ~1e-14, divided by the
// step: ~1e-8. Real mistakes are O(1e-3) or more.
diff::CheckOptions JacobianCheckOptions() {
  diff::CheckOptions options;
  options.relative_step = 1e-6;
  options.relative_tolerance = 1e-6;
  options.absolute_tolerance = 1e-7;
  return options;
}

TEST(FitcPredictTest, JacobiansMatchFiniteDifferences) {
  const Problem problem = MakeProblem(60, 1);
  absl::StatusOr<FitcModel> model = SparseModel(problem, 15, 2);
  TG_ASSERT_OK(model.status());
  const int p = 6;
  const RowMatrix z = MakeQueries(problem, p, 3);
  const PredictOptions options{25.0};  // GTP+sigma_n's multiplier: exercises the noise term
  RowMatrix mean, var, dmean, dvar;
  model->Predict(z, options, &mean, &var, &dmean, &dvar);
  ASSERT_EQ(dmean.rows(), p);
  ASSERT_EQ(dmean.cols(), 2 * 3);
  ASSERT_EQ(dvar.cols(), 2 * 3);
  const Vector x = Eigen::Map<const Vector>(z.data(), z.size());
  const diff::CheckResult mean_check = diff::CheckJacobian(
      PredictFunction(*model, options, p, false), x, BlockJacobian(dmean, 2, 3),
      JacobianCheckOptions());
  EXPECT_TRUE(mean_check.ok) << mean_check.log;
  const diff::CheckResult var_check = diff::CheckJacobian(
      PredictFunction(*model, options, p, true), x, BlockJacobian(dvar, 2, 3),
      JacobianCheckOptions());
  EXPECT_TRUE(var_check.ok) << var_check.log;
  // The check must be about something.
  EXPECT_GT(dmean.cwiseAbs().maxCoeff(), 0.1);
  EXPECT_GT(dvar.cwiseAbs().maxCoeff(), 0.01);
}

TEST(FitcPredictTest, WrongJacobiansFailTheCheck) {
  const Problem problem = MakeProblem(60, 1);
  absl::StatusOr<FitcModel> model = SparseModel(problem, 15, 2);
  TG_ASSERT_OK(model.status());
  const int p = 6;
  const RowMatrix z = MakeQueries(problem, p, 3);
  const PredictOptions options{25.0};
  RowMatrix mean, var, dmean, dvar;
  model->Predict(z, options, &mean, &var, &dmean, &dvar);
  const Vector x = Eigen::Map<const Vector>(z.data(), z.size());
  ::totalgrad::gp::testing::ExpectTypicalSlipsFailTheCheck(*model, z, options,
                                                          JacobianCheckOptions());
  // Swapping the outputs' variance blocks.
  RowMatrix swapped = dvar;
  swapped.leftCols(3) = dvar.rightCols(3);
  swapped.rightCols(3) = dvar.leftCols(3);
  EXPECT_FALSE(diff::CheckJacobian(PredictFunction(*model, options, p, true), x,
                                   BlockJacobian(swapped, 2, 3), JacobianCheckOptions())
                   .ok);
}

// With Z = X (M = N) FITC is the full GP up to the ridge r = 1e-6 on Kmm:
// Q = K (K + r I)^-1 K differs from K by at most r, so the FITC model is the
// full GP with its noise sn^2 raised by <= r on the diagonal (and its prior
// covariance lowered by <= r). Predictions then move by ~ r / sn^2 relative
// to their size: here sn^2 >= 0.09, so ~1e-5; we allow 5e-5 (relative to
// max(1, |value|)). A genuinely different model, inducing inputs a random
// half of the data, misses that tolerance (checked below), so the comparison
// is not vacuous.
TEST(FitcPredictTest, InducingInputsAtTheDataAgreeWithTheFullGp) {
  const Problem problem = MakeProblem(40, 4, 0.3, 0.4);
  absl::StatusOr<GpModel> full = GpModel::Create(problem.inputs, problem.targets, problem.hyp);
  TG_ASSERT_OK(full.status());
  absl::StatusOr<FitcModel> sparse =
      FitcModel::Create(problem.inputs, problem.targets, problem.hyp, problem.inputs);
  TG_ASSERT_OK(sparse.status());
  const RowMatrix z = MakeQueries(problem, 12, 5);
  for (const double mult : {0.0, 1.0, 25.0}) {
    RowMatrix fm, fv, fdm, fdv, sm, sv, sdm, sdv;
    full->Predict(z, PredictOptions{mult}, &fm, &fv, &fdm, &fdv);
    sparse->Predict(z, PredictOptions{mult}, &sm, &sv, &sdm, &sdv);
    EXPECT_TRUE(MatricesNear(sm, fm, 5e-5, 5e-5)) << "mult " << mult;
    EXPECT_TRUE(MatricesNear(sv, fv, 5e-5, 5e-5)) << "mult " << mult;
    EXPECT_TRUE(MatricesNear(sdm, fdm, 5e-5, 5e-5)) << "mult " << mult;
    EXPECT_TRUE(MatricesNear(sdv, fdv, 5e-5, 5e-5)) << "mult " << mult;
  }
  absl::StatusOr<FitcModel> half = SparseModel(problem, 20, 6);
  TG_ASSERT_OK(half.status());
  RowMatrix fm, fv, hm, hv;
  full->Predict(z, PredictOptions{}, &fm, &fv, nullptr, nullptr);
  half->Predict(z, PredictOptions{}, &hm, &hv, nullptr, nullptr);
  EXPECT_FALSE(MatricesNear(hm, fm, 5e-5, 5e-5) && MatricesNear(hv, fv, 5e-5, 5e-5));
}

TEST(FitcPredictTest, BatchEqualsSingleRowsAndRequestsDoNotChangeValues) {
  const Problem problem = MakeProblem(60, 7);
  absl::StatusOr<FitcModel> model = SparseModel(problem, 20, 8);
  TG_ASSERT_OK(model.status());
  const int p = 11;
  const RowMatrix z = MakeQueries(problem, p, 9);
  const PredictOptions options{25.0};
  RowMatrix mean, var, dmean, dvar, mean2, var2, mean3;
  model->Predict(z, options, &mean, &var, &dmean, &dvar);
  model->Predict(z, options, &mean2, &var2, nullptr, nullptr);
  model->Predict(z, options, &mean3, nullptr, nullptr, nullptr);  // mean only
  EXPECT_EQ(mean, mean2);  // bitwise: the same arithmetic whatever is requested
  EXPECT_EQ(var, var2);
  EXPECT_EQ(mean, mean3);
  for (int i = 0; i < p; ++i) {
    RowMatrix m1, v1, dm1, dv1;
    model->Predict(z.row(i), options, &m1, &v1, &dm1, &dv1);
    // gemv vs gemm summation order only (see gp_test.cc).
    EXPECT_TRUE(MatricesNear(m1, mean.row(i), 1e-11, 1e-10)) << "row " << i;
    EXPECT_TRUE(MatricesNear(v1, var.row(i), 1e-11, 1e-10)) << "row " << i;
    EXPECT_TRUE(MatricesNear(dm1, dmean.row(i), 1e-11, 1e-10)) << "row " << i;
    EXPECT_TRUE(MatricesNear(dv1, dvar.row(i), 1e-11, 1e-10)) << "row " << i;
  }
  // Far from every inducing input the prediction is the prior.
  RowMatrix far = RowMatrix::Constant(1, 3, 50.0), fm, fv;
  model->Predict(far, PredictOptions{0.0}, &fm, &fv, nullptr, nullptr);
  EXPECT_NEAR(fm(0, 0), 0.0, 1e-12);
  EXPECT_NEAR(fv(0, 0), 1.2 * 1.2, 1e-12);
  EXPECT_NEAR(fv(0, 1), 0.7 * 0.7, 1e-12);
  model->Predict(far, PredictOptions{25.0}, &fm, &fv, nullptr, nullptr);
  EXPECT_NEAR(fv(0, 1), 0.7 * 0.7 + 25 * 0.2 * 0.2, 1e-12);
  // Empty queries give empty outputs.
  model->Predict(RowMatrix(0, 3), options, &mean, &var, &dmean, &dvar);
  EXPECT_EQ(mean.rows(), 0);
  EXPECT_EQ(dvar.rows(), 0);
}

TEST(FitcFitTest, FitsFromARandomSubsetThenWarmStarts) {
  const Problem problem = MakeProblem(50, 11);
  RowMatrix inducing;
  Rng rng(12, Stream::kGpInit);
  FitcFitOptions options;
  options.num_inducing = 10;
  options.first_fit_iterations = 30;
  options.warm_fit_iterations = 5;
  FitcTrainingSummary summary;
  absl::StatusOr<FitcModel> first =
      FitFitcModel(problem.inputs, problem.targets, problem.hyp, options, &inducing, &rng, &summary);
  TG_ASSERT_OK(first.status());
  EXPECT_EQ(inducing.rows(), 10);
  EXPECT_EQ(first->inducing(), inducing);
  EXPECT_LT(summary.final_nlml, summary.initial_nlml);
  const double first_final = summary.final_nlml;
  absl::StatusOr<FitcModel> warm =
      FitFitcModel(problem.inputs, problem.targets, problem.hyp, options, &inducing, &rng, &summary);
  TG_ASSERT_OK(warm.status());
  EXPECT_DOUBLE_EQ(summary.initial_nlml, first_final);  // started where the first fit ended
  options.num_inducing = 51;
  EXPECT_EQ(FitFitcModel(problem.inputs, problem.targets, problem.hyp, options, &inducing, &rng,
                         nullptr)
                .status()
                .code(),
            absl::StatusCode::kInvalidArgument);
  options.num_inducing = 0;
  EXPECT_FALSE(
      FitFitcModel(problem.inputs, problem.targets, problem.hyp, options, &inducing, &rng, nullptr)
          .ok());
}

}  // namespace fitc_predict_test
}  // namespace totalgrad::gp
