// The low-rank-plus-diagonal predictive variance of GpModel
// (GpModelOptions::variance_rank_tolerance, core/gp/gp.h): tolerance 0 and
// the exact fallback are the exact path bit for bit; the variance's error
// stays within the stated a-priori bound (and is not trivially zero); the
// variance Jacobian is the derivative of the approximate variance; results
// do not depend on the thread count; bad tolerances are refused by name.
#include <gmock/gmock.h>
#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <limits>
#include <vector>

#include "core/common/rng.h"
#include "core/common/thread_pool.h"
#include "core/diff/gradient_checker.h"
#include "core/gp/gp.h"
#include "tests/core/gp/predict_check.h"
#include "tests/testutil/testutil.h"

namespace totalgrad::gp {
namespace {

using ::testing::HasSubstr;
using ::totalgrad::gp::testing::BlockJacobian;
using ::totalgrad::gp::testing::PredictFunction;

struct Problem {
  RowMatrix inputs;
  RowMatrix targets;
  GpHyperparameters hyp;
};

// N points in [-2, 2]^3, two outputs with different hyperparameters. With
// sf ~ 1 and sn = noise_std the kernel matrix's spectrum decays fast enough
// that a tolerance of 1e-2 .. 1e-6 needs a rank well below N/2.
Problem MakeProblem(int n, uint64_t seed, double noise_std0, double noise_std1) {
  Rng rng(seed, Stream::kStudy);
  Problem problem;
  problem.inputs.resize(n, 3);
  for (int i = 0; i < n; ++i)
    for (int m = 0; m < 3; ++m) problem.inputs(i, m) = rng.Uniform(-2.0, 2.0);
  problem.targets.resize(n, 2);
  for (int i = 0; i < n; ++i) {
    const auto x = problem.inputs.row(i);
    problem.targets(i, 0) = std::sin(x(0)) + x(1) * x(2) + noise_std0 * rng.Normal();
    problem.targets(i, 1) = std::cos(x(1)) - 0.3 * x(0) + noise_std1 * rng.Normal();
  }
  problem.hyp.log_lengthscales.resize(2, 3);
  problem.hyp.log_lengthscales << std::log(0.9), std::log(1.3), std::log(0.7),  //
      std::log(1.5), std::log(0.8), std::log(1.1);
  problem.hyp.log_signal_std.resize(2);
  problem.hyp.log_signal_std << std::log(1.2), std::log(0.7);
  problem.hyp.log_noise_std.resize(2);
  problem.hyp.log_noise_std << std::log(noise_std0), std::log(noise_std1);
  return problem;
}

// Half the queries near training inputs (small variance), half spread out.
RowMatrix MakeQueries(const Problem& problem, int p, uint64_t seed) {
  Rng rng(seed, Stream::kEvaluation);
  RowMatrix z(p, 3);
  for (int i = 0; i < p; ++i)
    for (int m = 0; m < 3; ++m)
      z(i, m) = i % 2 == 0 ? problem.inputs(i % problem.inputs.rows(), m) + 0.05 * rng.Normal()
                           : rng.Uniform(-2.5, 2.5);
  return z;
}

GpModel Build(const Problem& problem, double tolerance) {
  GpModelOptions options;
  options.variance_rank_tolerance = tolerance;
  absl::StatusOr<GpModel> model =
      GpModel::Create(problem.inputs, problem.targets, problem.hyp, options);
  TG_CHECK(model.ok());
  return *std::move(model);
}

struct Prediction {
  RowMatrix mean, var, dmean, dvar;
};
Prediction Predict(const GpModel& model, const RowMatrix& z, const PredictOptions& options,
                   ThreadPool* pool = nullptr) {
  Prediction out;
  model.Predict(z, options, &out.mean, &out.var, &out.dmean, &out.dvar, pool);
  return out;
}

TEST(LowRankVariance, ToleranceZeroIsTheExactPath) {
  const Problem problem = MakeProblem(120, 1, 0.1, 0.2);
  const GpModel exact = *GpModel::Create(problem.inputs, problem.targets, problem.hyp);
  const GpModel zero = Build(problem, 0.0);
  const RowMatrix z = MakeQueries(problem, 31, 2);
  const Prediction a = Predict(exact, z, PredictOptions{}), b = Predict(zero, z, PredictOptions{});
  for (int o = 0; o < 2; ++o) EXPECT_EQ(zero.rank(o), 120);
  EXPECT_EQ(a.mean, b.mean);
  EXPECT_EQ(a.var, b.var);
  EXPECT_EQ(a.dmean, b.dmean);
  EXPECT_EQ(a.dvar, b.dvar);
}

// Tiny noise: every eigenvalue above ~s matters, the bound needs r >= N/2,
// so the output keeps the exact product, bit for bit.
TEST(LowRankVariance, RankAtLeastHalfKeepsTheExactProduct) {
  const Problem problem = MakeProblem(60, 3, 1e-3, 0.1);
  const GpModel exact = Build(problem, 0.0);
  const GpModel fast = Build(problem, 1e-2);
  EXPECT_EQ(fast.rank(0), 60) << "output 0's bound should need r >= N/2 at sn = 1e-3";
  EXPECT_LT(2 * fast.rank(1), 60) << "output 1 should use the low-rank form";
  const RowMatrix z = MakeQueries(problem, 17, 4);
  const Prediction a = Predict(exact, z, PredictOptions{}), b = Predict(fast, z, PredictOptions{});
  EXPECT_EQ(a.mean, b.mean);  // the mean is always exact
  EXPECT_EQ(a.var.col(0), b.var.col(0));
  EXPECT_EQ(a.dvar.leftCols(3), b.dvar.leftCols(3));
  EXPECT_NE(a.var.col(1), b.var.col(1));
}

// 0 <= var_exact - var_fast <= t * s for every query, and relative error <= t
// (the variance includes the noise, no jitter here). Round-off of both paths
// is ~ eps * |k|^2 / s, far below t * s for the tolerances used; it is allowed
// for explicitly (kRoundOff) so that an exact 0 difference is not demanded.
TEST(LowRankVariance, ErrorWithinTheBoundAndNotVacuous) {
  for (uint64_t seed : {5, 6, 7}) {
    for (double tolerance : {1e-2, 1e-4, 1e-6}) {
      const Problem problem = MakeProblem(300, seed, 0.05, 0.1);
      const GpModel exact = Build(problem, 0.0);
      const GpModel fast = Build(problem, tolerance);
      const RowMatrix z = MakeQueries(problem, 200, seed + 100);
      for (double mult : {1.0, 25.0}) {
        const PredictOptions options{mult};
        const Prediction a = Predict(exact, z, options), b = Predict(fast, z, options);
        EXPECT_EQ(a.mean, b.mean);
        for (int o = 0; o < 2; ++o) {
          SCOPED_TRACE(::testing::Message() << "seed " << seed << " t " << tolerance
                                            << " output " << o << " mult " << mult);
          const int r = fast.rank(o);
          EXPECT_GT(r, 0);
          EXPECT_LT(2 * r, 300);
          ASSERT_EQ(fast.jitter(o), 0.0);
          const double s = std::exp(2 * problem.hyp.log_noise_std(o));
          const double prior = std::exp(2 * problem.hyp.log_signal_std(o)) + mult * s;
          const double kRoundOff = 1e-12 * prior;
          double max_rel = 0;
          for (int i = 0; i < z.rows(); ++i) {
            const double diff = a.var(i, o) - b.var(i, o);
            EXPECT_GE(diff, -kRoundOff) << "query " << i;
            EXPECT_LE(diff, tolerance * s + kRoundOff) << "query " << i;
            max_rel = std::max(max_rel, std::abs(diff) / a.var(i, o));
          }
          EXPECT_LE(max_rel, tolerance * (1 + 1e-9));
          // Not vacuous: the approximation changes the variance measurably
          // (well above round-off) somewhere.
          EXPECT_GT(max_rel, 1e3 * kRoundOff / prior);
        }
      }
    }
  }
}

// Central differences of the approximate variance, as gp_test's exact check
// (same step and tolerances).
TEST(LowRankVariance, JacobianMatchesFiniteDifferences) {
  const Problem problem = MakeProblem(150, 8, 0.05, 0.1);
  const GpModel fast = Build(problem, 1e-3);
  ASSERT_LT(2 * fast.rank(0), 150);
  ASSERT_LT(2 * fast.rank(1), 150);
  const int p = 6;
  const RowMatrix z = MakeQueries(problem, p, 9);
  const PredictOptions options{25.0};
  RowMatrix mean, var, dmean, dvar;
  fast.Predict(z, options, &mean, &var, &dmean, &dvar);
  const Vector x = Eigen::Map<const Vector>(z.data(), z.size());
  diff::CheckOptions check;
  check.relative_step = 1e-6;
  check.relative_tolerance = 1e-6;
  check.absolute_tolerance = 1e-7;
  const diff::CheckResult var_check = diff::CheckJacobian(
      PredictFunction(fast, options, p, true), x, BlockJacobian(dvar, 2, 3), check);
  EXPECT_TRUE(var_check.ok) << var_check.log;
  EXPECT_GT(dvar.cwiseAbs().maxCoeff(), 0.01);
  // And the typical slips (sign, factor, length-scale) fail that check.
  ::totalgrad::gp::testing::ExpectTypicalSlipsFailTheCheck(fast, z, options, check);
}

TEST(LowRankVariance, SameBitsForAnyThreadCount) {
  const Problem problem = MakeProblem(200, 10, 0.05, 0.1);
  const GpModel fast = Build(problem, 1e-4);
  ASSERT_LT(2 * fast.rank(0), 200);
  const RowMatrix z = MakeQueries(problem, 70, 11);
  const Prediction serial = Predict(fast, z, PredictOptions{});
  for (int threads : {2, 3}) {
    ThreadPool pool(threads);
    // Twice: the second call runs on workspaces already sized by the first
    // (and by the other output's rank).
    for (int rep = 0; rep < 2; ++rep) {
      const Prediction parallel = Predict(fast, z, PredictOptions{}, &pool);
      EXPECT_EQ(serial.mean, parallel.mean);
      EXPECT_EQ(serial.var, parallel.var) << threads << " threads";
      EXPECT_EQ(serial.dmean, parallel.dmean);
      EXPECT_EQ(serial.dvar, parallel.dvar) << threads << " threads";
    }
  }
  // A larger batch after smaller ones, on threads whose buffers were sized
  // for 70 queries: the flat buffer grows, the numbers stay the same bits.
  const RowMatrix big = MakeQueries(problem, 140, 12);
  const Prediction big_serial = Predict(fast, big, PredictOptions{});
  ThreadPool pool(2);
  Predict(fast, z, PredictOptions{}, &pool);
  const Prediction big_parallel = Predict(fast, big, PredictOptions{}, &pool);
  EXPECT_EQ(big_serial.var, big_parallel.var);
  EXPECT_EQ(big_serial.dvar, big_parallel.dvar);
}

TEST(LowRankVariance, BadTolerancesAreRefusedByName) {
  const Problem problem = MakeProblem(20, 13, 0.1, 0.2);
  for (double bad : {-1e-3, 1.0, 2.0, std::numeric_limits<double>::quiet_NaN(),
                     std::numeric_limits<double>::infinity()}) {
    GpModelOptions options;
    options.variance_rank_tolerance = bad;
    const absl::StatusOr<GpModel> model =
        GpModel::Create(problem.inputs, problem.targets, problem.hyp, options);
    ASSERT_FALSE(model.ok()) << bad;
    EXPECT_EQ(model.status().code(), absl::StatusCode::kInvalidArgument);
    EXPECT_THAT(model.status().message(), HasSubstr("variance_rank_tolerance")) << bad;
  }
}

}  // namespace
}  // namespace totalgrad::gp
