// Intervals on paired differences (results/paired_intervals.h) against
// cases worked by hand.
#include "results/paired_intervals.h"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>

namespace totalgrad::results {
namespace paired_intervals_test {

TEST(NewcombePairedIntervalTest, MatchesAHandWorkedTable) {
  // 10 pairs: both 5, first only 3, second only 1, neither 1.
  // p1 = 8/10, p2 = 6/10, d = 0.2. Wilson 95%: 8/10 -> (0.490162, 0.943318),
  // 6/10 -> (0.312674, 0.831820). phi = (5*1 - 3*1) / sqrt(8*2*6*4)
  // = 2 / sqrt(384) = 0.102062.
  // low  = 0.2 - sqrt(0.309838^2 - 2 phi 0.309838 * 0.231820 + 0.231820^2)
  //      = -0.167530,
  // high = 0.2 + sqrt(0.287326^2 - 2 phi 0.287326 * 0.143318 + 0.143318^2)
  //      = 0.507719.
  const RateDifferenceInterval interval = NewcombePairedInterval({5, 3, 1, 1});
  EXPECT_EQ(interval.pairs, 10);
  EXPECT_NEAR(interval.difference, 0.2, 1e-15);
  EXPECT_NEAR(interval.low, -0.1675297868156374, 1e-12);
  EXPECT_NEAR(interval.high, 0.507718613018509, 1e-12);
}

TEST(NewcombePairedIntervalTest, AllDiscordancyOneWayExcludesZero) {
  // 6 of 10 pairs only the first succeeded, none only the second: p1 = 0.6,
  // p2 = 0, phi = 0 (the margin "both + second only" is empty), so the
  // bounds are the independent Newcombe's: low = 0.6 - sqrt((0.6 -
  // 0.312674)^2 + 0.277533^2) = 0.200524, high = 0.6 + (0.831820 - 0.6).
  const RateDifferenceInterval interval = NewcombePairedInterval({0, 6, 0, 4});
  EXPECT_NEAR(interval.difference, 0.6, 1e-15);
  EXPECT_NEAR(interval.low, 0.20052432164297995, 1e-12);
  EXPECT_NEAR(interval.high, 0.8318196702937638, 1e-12);
}

TEST(NewcombePairedIntervalTest, IsSymmetricUnderSwappingTheMethods) {
  const RateDifferenceInterval forward = NewcombePairedInterval({4, 2, 1, 3});
  const RateDifferenceInterval backward = NewcombePairedInterval({4, 1, 2, 3});
  EXPECT_NEAR(forward.difference, -backward.difference, 1e-15);
  EXPECT_NEAR(forward.low, -backward.high, 1e-12);
  EXPECT_NEAR(forward.high, -backward.low, 1e-12);
  EXPECT_LT(forward.low, forward.difference);
  EXPECT_GT(forward.high, forward.difference);
}

TEST(NewcombePairedIntervalTest, StaysWithinMinusOneAndOne) {
  const RateDifferenceInterval all = NewcombePairedInterval({0, 10, 0, 0});
  EXPECT_DOUBLE_EQ(all.difference, 1.0);
  EXPECT_LE(all.high, 1.0);
  EXPECT_GT(all.low, 0.5);
}

TEST(NewcombePairedIntervalTest, NoPairsIsNaN) {
  const RateDifferenceInterval none = NewcombePairedInterval({});
  EXPECT_EQ(none.pairs, 0);
  EXPECT_TRUE(std::isnan(none.difference));
  EXPECT_TRUE(std::isnan(none.low));
  EXPECT_TRUE(std::isnan(none.high));
}

TEST(HodgesLehmannIntervalTest, MatchesTheWalshAveragesWorkedByHand) {
  // n = 10: 55 Walsh averages. Under the null, P(T+ <= 8) = 25/1024 =
  // 0.0244 < 0.025 <= P(T+ <= 9) = 33/1024, so k = 9 and the interval is
  // [W_(9), W_(47)]; coverage 1 - 2 * 25/1024 = 0.951171875. Sorted Walsh
  // averages of these differences: W_(9) = 1.3, W_(28) (the median) = 3.9,
  // W_(47) = 6.7.
  const std::vector<double> differences = {-2.1, 0.4, 1.3, 2.2, 3.5, 4.0, 5.8, 6.1, 7.7, 9.9};
  const ShiftInterval interval = HodgesLehmannInterval(differences);
  EXPECT_EQ(interval.n, 10);
  EXPECT_NEAR(interval.estimate, 3.9, 1e-12);
  EXPECT_NEAR(interval.low, 1.3, 1e-12);
  EXPECT_NEAR(interval.high, 6.7, 1e-12);
  EXPECT_DOUBLE_EQ(interval.coverage, 1 - 2 * 25.0 / 1024);
}

TEST(HodgesLehmannIntervalTest, FiveDifferencesCannotReachNinetyFivePercent) {
  // n = 5: P(T+ <= 0) = 1/32 > 0.025, so no k reaches the level and k = 1:
  // the interval is [W_(1), W_(15)], the smallest and largest difference,
  // and the coverage reported is 1 - 2 P(T+ <= 0) = 0.9375, below 95%.
  const ShiftInterval interval = HodgesLehmannInterval({3, -1, 4, 1, 5});
  EXPECT_DOUBLE_EQ(interval.low, -1);
  EXPECT_DOUBLE_EQ(interval.high, 5);
  EXPECT_DOUBLE_EQ(interval.estimate, 2.5);  // median of 15 Walsh averages
  EXPECT_DOUBLE_EQ(interval.coverage, 1 - 2.0 / 32);
}

TEST(HodgesLehmannIntervalTest, DropsNaNAndShiftsWithTheData) {
  const std::vector<double> base = {-2.1, 0.4, 1.3, 2.2, 3.5, 4.0, 5.8, 6.1, 7.7, 9.9};
  std::vector<double> shifted;
  for (double d : base) shifted.push_back(d - 10);
  shifted.push_back(std::numeric_limits<double>::quiet_NaN());
  const ShiftInterval interval = HodgesLehmannInterval(shifted);
  EXPECT_EQ(interval.n, 10);
  EXPECT_NEAR(interval.estimate, 3.9 - 10, 1e-12);
  EXPECT_NEAR(interval.low, 1.3 - 10, 1e-12);
  EXPECT_NEAR(interval.high, 6.7 - 10, 1e-12);
}

TEST(HodgesLehmannIntervalTest, NoDifferenceIsNaN) {
  const ShiftInterval interval = HodgesLehmannInterval({std::nan("")});
  EXPECT_EQ(interval.n, 0);
  EXPECT_TRUE(std::isnan(interval.estimate));
  EXPECT_TRUE(std::isnan(interval.low));
}

}  // namespace paired_intervals_test
}  // namespace totalgrad::results
