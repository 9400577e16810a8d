// The equal-time comparison (core/study/equal_time.h): log-log interpolation
// on known power laws, "n/a" outside the measured range and next to cells
// that could not be measured, the winner and the ratios, no winner where the
// reference estimators disagree, the noise-floor flag, PILCO as a point.
#include "core/study/equal_time.h"

#include <gtest/gtest.h>

#include <cmath>

namespace totalgrad::study {
namespace equal_time_test {

constexpr double kNaN = CellResult::kNaN;

// error = a * t^slope at the given times: a straight line in log-log.
std::vector<TimeErrorPoint> PowerLaw(double a, double slope, const std::vector<double>& times) {
  std::vector<TimeErrorPoint> points;
  for (double t : times) points.push_back({t, a * std::pow(t, slope)});
  return points;
}

TEST(InterpolateErrorAtTime, IsExactOnAPowerLaw) {
  const std::vector<TimeErrorPoint> curve = PowerLaw(0.02, -0.5, {1e-3, 4e-3, 3e-2, 0.5});
  for (double t : {1e-3, 2e-3, 1e-2, 0.1, 0.5}) {
    EXPECT_NEAR(InterpolateErrorAtTime(curve, t), 0.02 * std::pow(t, -0.5), 1e-12 * std::pow(t, -0.5))
        << t;
  }
}

// Linear interpolation in (log t, log e), not in (t, e): between (1e-3, 1)
// and (1e-1, 1e-2), at 1e-2 the error is 0.1 (a linear interpolation would
// give ~0.9).
TEST(InterpolateErrorAtTime, IsLogLogNotLinear) {
  const std::vector<TimeErrorPoint> curve = {{1e-3, 1.0}, {1e-1, 1e-2}};
  EXPECT_NEAR(InterpolateErrorAtTime(curve, 1e-2), 0.1, 1e-12);
}

TEST(InterpolateErrorAtTime, IsNotAvailableOutsideTheMeasuredRange) {
  const std::vector<TimeErrorPoint> curve = PowerLaw(1.0, -0.5, {1e-2, 1e-1});
  EXPECT_TRUE(std::isnan(InterpolateErrorAtTime(curve, 9.9e-3)));
  EXPECT_TRUE(std::isnan(InterpolateErrorAtTime(curve, 0.11)));
  EXPECT_FALSE(std::isnan(InterpolateErrorAtTime(curve, 1e-2)));
  EXPECT_FALSE(std::isnan(InterpolateErrorAtTime(curve, 1e-1)));
  EXPECT_TRUE(std::isnan(InterpolateErrorAtTime({}, 1e-2)));
  // One measured point covers its own time only.
  EXPECT_EQ(InterpolateErrorAtTime({{1e-2, 0.3}}, 1e-2), 0.3);
  EXPECT_TRUE(std::isnan(InterpolateErrorAtTime({{1e-2, 0.3}}, 1.1e-2)));
}

// A cell that could not be measured breaks the curve: no interpolation
// across it.
TEST(InterpolateErrorAtTime, DoesNotBridgeAnUnmeasuredCell) {
  const std::vector<TimeErrorPoint> curve = {{1e-3, 1.0}, {kNaN, kNaN}, {1e-1, 0.1}};
  EXPECT_TRUE(std::isnan(InterpolateErrorAtTime(curve, 1e-2)));
  const std::vector<TimeErrorPoint> zero_error = {{1e-3, 1.0}, {1e-1, 0.0}};
  EXPECT_TRUE(std::isnan(InterpolateErrorAtTime(zero_error, 1e-2)));
}

// Timing noise can make a larger P faster; every bracketing pair counts and
// the lowest error wins.
TEST(InterpolateErrorAtTime, TakesTheLowestErrorWhereTimesAreNotMonotone) {
  const std::vector<TimeErrorPoint> curve = {{1e-3, 1.0}, {1e-1, 0.5}, {1e-2, 0.01}};
  // Segment 1 at 1e-2: 10^(-0.5 * log10 2) ~ 0.707; segment 2 at 1e-2: 0.01.
  EXPECT_NEAR(InterpolateErrorAtTime(curve, 1e-2), 0.01, 1e-15);
  EXPECT_NEAR(InterpolateErrorAtTime(curve, 3e-3), std::pow(0.5, std::log10(3.0) / 2.0), 1e-12);
}

CellResult Cell(const std::string& estimator, int p, int h, double seconds, double error) {
  CellResult c;
  c.estimator = estimator;
  c.method = estimator;
  c.particles = p;
  c.horizon = h;
  c.replicates = 8;
  c.time_min_s = seconds;
  c.rel_rmse = error;
  return c;
}

StudyResult TwoEstimatorStudy(bool agree) {
  StudyResult r;
  ReferenceGradient ref;
  ref.horizon = 10;
  ref.norm = 1.0;
  ref.floor = 0.05;
  ref.agree = agree;
  r.references = {ref};
  // A: fast and noisy (error 0.1 / sqrt(t / 1 ms)); B: 4x slower for the same error.
  for (int p : {10, 100, 1000}) {
    const double t = 1e-3 * p / 10.0;
    r.cells.push_back(Cell("A", p, 10, t, 0.1 * std::sqrt(1e-3 / t)));
    r.cells.push_back(Cell("B", p, 10, 4 * t, 0.1 * std::sqrt(1e-3 / t)));
  }
  CellResult pilco = Cell("PILCO", 0, 10, 0.02, 0.7);
  pilco.replicates = 1;
  r.cells.push_back(pilco);
  return r;
}

TEST(CompareAtEqualTime, NamesTheWinnerAndTheRatios) {
  const EqualTimeComparison cmp = CompareAtEqualTime(TwoEstimatorStudy(true), {1e-2, 1e-3, 1.0});
  ASSERT_EQ(cmp.rows.size(), 3u);
  const EqualTimeRow& row = cmp.rows[0];
  EXPECT_EQ(row.horizon, 10);
  EXPECT_EQ(row.seconds, 1e-2);
  ASSERT_EQ(row.estimators, (std::vector<std::string>{"A", "B"}));  // PILCO has no curve
  EXPECT_EQ(row.winner, "A");
  EXPECT_NEAR(row.winner_error, 0.1 * std::sqrt(0.1), 1e-12);
  EXPECT_DOUBLE_EQ(row.ratios[0], 1.0);
  // B needs 4x the time for A's error: at equal time its error is sqrt(4) = 2x.
  EXPECT_NEAR(row.ratios[1], 2.0, 1e-12);
  EXPECT_TRUE(row.winner_below_floor == (row.winner_error < 0.05));
  // At 1 ms only A was measured (B starts at 4 ms): A wins, B is n/a.
  EXPECT_EQ(cmp.rows[1].winner, "A");
  EXPECT_TRUE(std::isnan(cmp.rows[1].errors[1]));
  EXPECT_TRUE(std::isnan(cmp.rows[1].ratios[1]));
  // At 1 s: A's range ends at 0.1 s; B (up to 0.4 s) too: no winner.
  EXPECT_TRUE(cmp.rows[2].winner.empty());
  ASSERT_EQ(cmp.fixed_cost.size(), 1u);
  EXPECT_EQ(cmp.fixed_cost[0].estimator, "PILCO");
  EXPECT_EQ(cmp.fixed_cost[0].seconds, 0.02);
  EXPECT_EQ(cmp.fixed_cost[0].error, 0.7);
}

TEST(CompareAtEqualTime, NoWinnerWhereTheReferencesDisagree) {
  const EqualTimeComparison cmp = CompareAtEqualTime(TwoEstimatorStudy(false), {1e-2});
  ASSERT_EQ(cmp.rows.size(), 1u);
  EXPECT_FALSE(cmp.rows[0].reference_agrees);
  EXPECT_TRUE(cmp.rows[0].winner.empty());
  EXPECT_TRUE(std::isnan(cmp.rows[0].ratios[0]));
  EXPECT_TRUE(std::isnan(cmp.rows[0].ratios[1]));
}

TEST(CompareAtEqualTime, FlagsAWinnerBelowTheNoiseFloor) {
  StudyResult r = TwoEstimatorStudy(true);
  r.references[0].floor = 0.5;  // every error is below it
  const EqualTimeComparison cmp = CompareAtEqualTime(r, {1e-2});
  EXPECT_EQ(cmp.rows[0].winner, "A");
  EXPECT_TRUE(cmp.rows[0].winner_below_floor);
  r.references[0].floor = 1e-4;
  EXPECT_FALSE(CompareAtEqualTime(r, {1e-2}).rows[0].winner_below_floor);
}

// An omitted or non-finite cell is not a measurement.
TEST(CompareAtEqualTime, SkipsOmittedCells) {
  StudyResult r = TwoEstimatorStudy(true);
  for (CellResult& c : r.cells) {
    if (c.estimator == "A" && c.particles == 100) c.omitted = true;
  }
  for (CellResult& c : r.cells) {
    if (c.estimator == "PILCO") {
      c.omitted = true;
      c.omission_reason = "two angles";
    }
  }
  const EqualTimeComparison cmp = CompareAtEqualTime(r, {5e-3});
  // A is broken between 1 ms and 100 ms; B (4 .. 400 ms) covers 5 ms.
  EXPECT_TRUE(std::isnan(cmp.rows[0].errors[0]));
  EXPECT_EQ(cmp.rows[0].winner, "B");
  // The omitted PILCO point keeps its reason and has no measurement.
  ASSERT_EQ(cmp.fixed_cost.size(), 1u);
  EXPECT_EQ(cmp.fixed_cost[0].omission_reason, "two angles");
  EXPECT_TRUE(std::isnan(cmp.fixed_cost[0].error));
}

// "n/a outside the measured range" must not hide a better answer: A's largest
// P (0.1 s, error 0.01) beats B's interpolated error at 0.2 s (0.0141), and
// at 1 s, which no curve reaches, A's 0.01 is still the best measured within
// 1 s. Where the winner is at least as good, nothing is named.
TEST(CompareAtEqualTime, NamesALowerErrorMeasuredInLessTime) {
  const EqualTimeComparison cmp = CompareAtEqualTime(TwoEstimatorStudy(true), {0.2, 1.0, 1e-2});
  ASSERT_EQ(cmp.rows.size(), 3u);
  const EqualTimeRow& at_02 = cmp.rows[0];
  EXPECT_EQ(at_02.winner, "B");
  EXPECT_NEAR(at_02.winner_error, 0.1 * std::sqrt(1e-3 / 0.05), 1e-12);
  EXPECT_TRUE(std::isnan(at_02.errors[0]));  // A: n/a at 0.2 s
  EXPECT_EQ(at_02.best_within, "A");
  EXPECT_EQ(at_02.best_within_particles, 1000);
  EXPECT_DOUBLE_EQ(at_02.best_within_seconds, 0.1);
  EXPECT_NEAR(at_02.best_within_error, 0.01, 1e-15);
  const EqualTimeRow& at_1 = cmp.rows[1];
  EXPECT_TRUE(at_1.winner.empty());
  EXPECT_EQ(at_1.best_within, "A");  // B's P = 1000 ties at 0.01 in 0.4 s: the first wins
  EXPECT_EQ(at_1.best_within_particles, 1000);
  const EqualTimeRow& at_10ms = cmp.rows[2];
  EXPECT_EQ(at_10ms.winner, "A");
  EXPECT_TRUE(at_10ms.best_within.empty());
  EXPECT_TRUE(std::isnan(at_10ms.best_within_error));
  // Where the references disagree nothing is named.
  EXPECT_TRUE(CompareAtEqualTime(TwoEstimatorStudy(false), {0.2}).rows[0].best_within.empty());
}

// A reference whose agreement check had no power (resolution > 1) still
// gives a winner, marked unchecked; an unknown resolution (older results)
// counts as checked.
TEST(CompareAtEqualTime, MarksRowsWhoseReferenceCheckHadNoPower) {
  StudyResult r = TwoEstimatorStudy(true);
  EXPECT_TRUE(CompareAtEqualTime(r, {1e-2}).rows[0].reference_checked);  // NaN
  r.references[0].agreement_resolution = 0.3;
  EXPECT_TRUE(CompareAtEqualTime(r, {1e-2}).rows[0].reference_checked);
  r.references[0].agreement_resolution = 160;
  const EqualTimeRow row = CompareAtEqualTime(r, {1e-2}).rows[0];
  EXPECT_FALSE(row.reference_checked);
  EXPECT_EQ(row.winner, "A");
}

}  // namespace equal_time_test
}  // namespace totalgrad::study
