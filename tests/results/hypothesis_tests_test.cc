// The comparison statistics (results/hypothesis_tests.h and
// comparison.h) against values worked out by hand or published; the
// comparison with SciPy on random inputs is stats_scipy_test.py.
#include "results/hypothesis_tests.h"

#include <gtest/gtest.h>

#include <cmath>

#include "results/comparison.h"

namespace totalgrad::results {
namespace hypothesis_tests_test {

// Probabilities come from lgamma: equal to the rational values to ~1e-15.
TEST(BinomialTestTest, SymmetricCasesWorkedByHand) {
  // 1 of 7 at 1/2: 2 * (1 + 7) / 2^7.
  EXPECT_NEAR(BinomialTestTwoSided(1, 7), 16.0 / 128, 1e-14);
  EXPECT_NEAR(BinomialTestTwoSided(6, 7), 16.0 / 128, 1e-14);
  // 0 of 5: 2 / 32.
  EXPECT_NEAR(BinomialTestTwoSided(0, 5), 2.0 / 32, 1e-14);
  // The centre, and nothing to test.
  EXPECT_DOUBLE_EQ(BinomialTestTwoSided(3, 6), 1.0);
  EXPECT_DOUBLE_EQ(BinomialTestTwoSided(0, 0), 1.0);
  EXPECT_TRUE(std::isnan(BinomialTestTwoSided(4, 3)));
}

TEST(BinomialTestTest, AsymmetricNullSumsOutcomesNoMoreProbable) {
  // 0 of 3 at p = 0.1: pmf 0.729, 0.243, 0.027, 0.001; the observed outcome
  // is the most probable, so every outcome counts.
  EXPECT_NEAR(BinomialTestTwoSided(0, 3, 0.1), 1.0, 1e-12);
  // 2 of 3: pmf 0.027 -> 0.027 + 0.001.
  EXPECT_NEAR(BinomialTestTwoSided(2, 3, 0.1), 0.028, 1e-12);
}

TEST(McNemarTest, IsTheBinomialTestOfTheDiscordantPairs) {
  EXPECT_NEAR(McNemarExactP(1, 6), 16.0 / 128, 1e-14);
  EXPECT_NEAR(McNemarExactP(0, 5), 2.0 / 32, 1e-14);
  EXPECT_DOUBLE_EQ(McNemarExactP(0, 0), 1.0);
  EXPECT_DOUBLE_EQ(McNemarExactP(4, 4), 1.0);
}

TEST(McNemarTest, PowerAtNoEffectIsAtMostAlphaAndGrowsWithTheEffect) {
  // No effect: the rejection rate is the test's size, below alpha (exact
  // tests are conservative).
  const double size = McNemarExactPower(40, 0.2, 0.2);
  EXPECT_GT(size, 0.0);
  EXPECT_LE(size, 0.05);
  // Worked by hand: 5 pairs, every pair discordant "first only" with
  // probability 1: b = 5 of d = 5 gives p = 2/32 > 0.05, never rejected.
  EXPECT_DOUBLE_EQ(McNemarExactPower(5, 1.0, 0.0), 0.0);
  // 6 pairs: b = 6 of 6 gives p = 2/64 < 0.05: always rejected.
  EXPECT_DOUBLE_EQ(McNemarExactPower(6, 1.0, 0.0), 1.0);
  const double medium = McNemarExactPower(40, 0.3, 0.05);
  const double large_n = McNemarExactPower(200, 0.3, 0.05);
  EXPECT_GT(medium, size);
  EXPECT_GT(large_n, medium);
  EXPECT_GT(large_n, 0.999);
  EXPECT_DOUBLE_EQ(McNemarExactPower(10, 0.0, 0.0), 0.0);
  EXPECT_TRUE(std::isnan(McNemarExactPower(10, 0.7, 0.7)));
}

TEST(FisherTest, PublishedExamples) {
  // Fisher's lady tasting tea (3 of 4 cups right): 34/70.
  EXPECT_NEAR(FisherExactP(3, 1, 1, 3), 34.0 / 70, 1e-12);
  // The example in Wikipedia's "Fisher's exact test" (dieting by sex).
  EXPECT_NEAR(FisherExactP(1, 9, 11, 3), 0.0027594561852200836, 1e-12);
  // Symmetric in rows and in columns.
  EXPECT_NEAR(FisherExactP(11, 3, 1, 9), FisherExactP(1, 9, 11, 3), 1e-15);
  EXPECT_NEAR(FisherExactP(9, 1, 3, 11), FisherExactP(1, 9, 11, 3), 1e-15);
  // A zero margin: nothing to test.
  EXPECT_DOUBLE_EQ(FisherExactP(0, 5, 0, 5), 1.0);
  EXPECT_DOUBLE_EQ(OddsRatio(3, 1, 1, 3), 9.0);
  EXPECT_TRUE(std::isinf(OddsRatio(3, 0, 1, 3)));
  EXPECT_TRUE(std::isnan(OddsRatio(0, 0, 1, 3)));
}

TEST(FisherTest, PowerAtNoEffectIsAtMostAlphaAndReachesOneForHugeEffects) {
  const double size = FisherExactPower(30, 0.4, 30, 0.4);
  EXPECT_LE(size, 0.05);
  EXPECT_GT(FisherExactPower(30, 0.9, 30, 0.1), 0.999);
  // 3 vs 3 trials can never reach p < 0.05 (the most extreme table, 3/3 vs
  // 0/3, has p = 0.1): power 0 whatever the truth.
  EXPECT_NEAR(FisherExactP(3, 0, 0, 3), 0.1, 1e-12);
  EXPECT_DOUBLE_EQ(FisherExactPower(3, 1.0, 3, 0.0), 0.0);
  // 4 vs 4: 4/4 vs 0/4 has p = 2/70 < 0.05, and with certain outcomes that
  // table always occurs.
  EXPECT_DOUBLE_EQ(FisherExactPower(4, 1.0, 4, 0.0), 1.0);
}

TEST(WilcoxonTest, ExactPValuesWorkedByHand) {
  // Ten positive differences: W+ = 55, the most extreme of 2^10 sign
  // assignments on either side.
  WilcoxonResult all_positive = WilcoxonSignedRank({1, 2, 3, 4, 5, 6, 7, 8, 9, 10});
  EXPECT_TRUE(all_positive.exact);
  EXPECT_EQ(all_positive.n, 10);
  EXPECT_DOUBLE_EQ(all_positive.w_plus, 55);
  EXPECT_DOUBLE_EQ(all_positive.p, 2.0 / 1024);
  EXPECT_DOUBLE_EQ(all_positive.rank_biserial, 1.0);
  // The smallest negative: W- = 1, and W+ >= 54 happens in 2 of 1024.
  WilcoxonResult one_negative = WilcoxonSignedRank({-1, 2, 3, 4, 5, 6, 7, 8, 9, 10});
  EXPECT_DOUBLE_EQ(one_negative.w_minus, 1);
  EXPECT_DOUBLE_EQ(one_negative.p, 4.0 / 1024);
  EXPECT_NEAR(one_negative.rank_biserial, (54.0 - 1.0) / 55.0, 1e-15);
}

TEST(WilcoxonTest, TiesUseMidranksAndTheExactConditionalDistribution) {
  // |d| = 1, 2, 2, 2: ranks 1 and 3, 3, 3 (doubled 2, 6, 6, 6; sum 20).
  // 2W+ = 18; sums >= 18: {6,6,6} and {2,6,6,6}: 2 of 16, so p = 4/16.
  WilcoxonResult r = WilcoxonSignedRank({2, 2, 2, -1});
  EXPECT_TRUE(r.ties);
  EXPECT_TRUE(r.exact);
  EXPECT_DOUBLE_EQ(r.w_plus, 9);
  EXPECT_DOUBLE_EQ(r.w_minus, 1);
  EXPECT_DOUBLE_EQ(r.p, 0.25);
  // All equal magnitudes, one negative of three: the centre-adjacent
  // outcome; P(2W+ >= 8) = 4/8, P(<= 8) = 7/8: p = 1.
  EXPECT_DOUBLE_EQ(WilcoxonSignedRank({1, 1, -1}).p, 1.0);
}

TEST(WilcoxonTest, ZerosAreDroppedAndNothingLeftMeansNoTest) {
  WilcoxonResult r = WilcoxonSignedRank({0, 0, 1, 2, 3});
  EXPECT_EQ(r.zeros, 2);
  EXPECT_EQ(r.n, 3);
  EXPECT_DOUBLE_EQ(r.p, 2.0 / 8);
  WilcoxonResult none = WilcoxonSignedRank({0, 0});
  EXPECT_EQ(none.n, 0);
  EXPECT_DOUBLE_EQ(none.p, 1.0);
  EXPECT_DOUBLE_EQ(none.hodges_lehmann, 0.0);
  EXPECT_TRUE(std::isnan(WilcoxonSignedRank({}).hodges_lehmann));
}

TEST(WilcoxonTest, HodgesLehmannIsTheMedianOfWalshAverages) {
  // Walsh averages of {1, 2, 3}: 1, 1.5, 2, 2, 2.5, 3 -> 2.
  EXPECT_DOUBLE_EQ(WilcoxonSignedRank({1, 2, 3}).hodges_lehmann, 2.0);
  // {-4, 1}: -4, -1.5, 1 -> -1.5.
  EXPECT_DOUBLE_EQ(WilcoxonSignedRank({-4, 1}).hodges_lehmann, -1.5);
}

TEST(WilcoxonTest, LargeSamplesUseTheNormalApproximation) {
  std::vector<double> d;
  for (int i = 1; i <= 60; ++i) d.push_back(i % 3 == 0 ? -i : i);
  const WilcoxonResult r = WilcoxonSignedRank(d);
  EXPECT_FALSE(r.exact);
  EXPECT_EQ(r.n, 60);
  // W- = 3 + 6 + ... + 60 = 630 of 1830; z = (630 - 915) / sqrt(60*61*121/24).
  const double z = (630 - 915) / std::sqrt(60.0 * 61 * 121 / 24);
  EXPECT_NEAR(r.p, 2 * NormalCdf(z), 1e-12);
}

TEST(NoetherPowerTest, MatchesTheFormulaAndItsLimits) {
  // No effect: power is alpha's half-tail... Phi(-z) = 0.025.
  EXPECT_NEAR(WilcoxonPowerNoether(30, 0.5), 0.025, 1e-9);
  // n = 3 (z_0.975 + z_0.8)^2 / (3 (p' - 1/2)^2) gives 80% power by design.
  const double z_sum = NormalQuantile(0.975) + NormalQuantile(0.8);
  const int n = 50;
  const double p_prime = 0.5 + z_sum / std::sqrt(3.0 * n);
  EXPECT_NEAR(WilcoxonPowerNoether(n, p_prime), 0.8, 1e-9);
  EXPECT_DOUBLE_EQ(WilcoxonPowerNoether(0, 0.9), 0.0);
  EXPECT_DOUBLE_EQ(WalshPositiveFraction({1, 2, 3}), 1.0);
  EXPECT_DOUBLE_EQ(WalshPositiveFraction({1, -1}), 0.5);  // the pair sums to 0
  EXPECT_DOUBLE_EQ(WalshPositiveFraction({-3, 1, 1}), 1.0 / 3);
}

TEST(NormalTest, QuantileInvertsTheDistributionFunction) {
  EXPECT_NEAR(NormalQuantile(0.975), 1.959963984540054, 1e-12);
  EXPECT_NEAR(NormalQuantile(0.5), 0.0, 1e-14);
  EXPECT_NEAR(NormalQuantile(1e-10), -6.361340902404056, 1e-9);
  EXPECT_NEAR(NormalCdf(-1.959963984540054), 0.025, 1e-15);
  EXPECT_TRUE(std::isnan(NormalQuantile(0)));
}

TEST(HolmTest, StepDownAdjustmentWorkedByHand) {
  // Sorted 0.005, 0.01, 0.03, 0.04 -> x4, x3, x2, x1 = 0.02, 0.03, 0.06,
  // 0.04 -> monotone: 0.02, 0.03, 0.06, 0.06.
  const std::vector<double> adjusted = HolmAdjust({0.01, 0.04, 0.03, 0.005});
  ASSERT_EQ(adjusted.size(), 4u);
  EXPECT_DOUBLE_EQ(adjusted[0], 0.03);
  EXPECT_DOUBLE_EQ(adjusted[1], 0.06);
  EXPECT_DOUBLE_EQ(adjusted[2], 0.06);
  EXPECT_DOUBLE_EQ(adjusted[3], 0.02);
  // Capped at 1; NaN stays NaN and is not counted in m.
  const std::vector<double> capped = HolmAdjust({0.6, std::nan(""), 0.3});
  EXPECT_DOUBLE_EQ(capped[0], 0.6);
  EXPECT_TRUE(std::isnan(capped[1]));
  EXPECT_DOUBLE_EQ(capped[2], 0.6);
}

// ---- grouping into comparisons ----

std::vector<CompletedTrial> TwoMethods() {
  // Seeds 1..8 in one variant: A succeeds on 1..7, B on 1 and 2 only; A's
  // final costs are lower by 1..8; B has a seed 9 that A lacks.
  std::vector<CompletedTrial> trials;
  for (int seed = 1; seed <= 8; ++seed) {
    trials.push_back({"A", std::to_string(seed), "k=1", seed <= 7, 10.0 - seed});
    trials.push_back({"B", std::to_string(seed), "k=1", seed <= 2, 10.0});
  }
  trials.push_back({"B", "9", "k=1", false, 30.0});
  return trials;
}

TEST(CompareMethodsTest, PairsBySeedAndTestsEachWay) {
  absl::StatusOr<ComparisonReport> report = CompareMethods(TwoMethods(), {});
  ASSERT_TRUE(report.ok()) << report.status();
  ASSERT_EQ(report->comparisons.size(), 1u);
  const Comparison& c = report->comparisons[0];
  EXPECT_EQ(c.method, "A");
  EXPECT_EQ(c.other, "B");
  EXPECT_EQ(c.success.pairs, 8);             // seed 9 has no partner
  EXPECT_EQ(c.success.both, 2);
  EXPECT_EQ(c.success.method_only, 5);
  EXPECT_EQ(c.success.other_only, 0);
  EXPECT_EQ(c.success.neither, 1);
  EXPECT_DOUBLE_EQ(c.success.difference, 5.0 / 8);
  EXPECT_DOUBLE_EQ(c.success.mcnemar_p, 2.0 / 32);
  EXPECT_DOUBLE_EQ(c.success.mcnemar_p_holm, c.success.mcnemar_p);  // a family of one
  // Differences -1..-8: all negative, W+ = 0, p = 2/256.
  EXPECT_EQ(c.cost_pairs, 8);
  EXPECT_DOUBLE_EQ(c.wilcoxon.w_plus, 0);
  EXPECT_DOUBLE_EQ(c.wilcoxon.p, 2.0 / 256);
  EXPECT_DOUBLE_EQ(c.wilcoxon.rank_biserial, -1.0);
  EXPECT_DOUBLE_EQ(c.wilcoxon.hodges_lehmann, -4.5);
  // Unpaired: 7/8 against 2/9.
  EXPECT_EQ(c.method_trials, 8);
  EXPECT_EQ(c.other_trials, 9);
  EXPECT_DOUBLE_EQ(c.fisher_p, FisherExactP(7, 1, 2, 7));
  EXPECT_GT(c.success.mcnemar_power, 0.0);
}

TEST(CompareMethodsTest, BaselineAndHolmPerVariant) {
  std::vector<CompletedTrial> trials = TwoMethods();
  for (int seed = 1; seed <= 8; ++seed) {
    trials.push_back({"C", std::to_string(seed), "k=1", seed <= 2, 10.0 + seed});
    trials.push_back({"A", std::to_string(seed), "k=2", true, 1.0});
    trials.push_back({"B", std::to_string(seed), "k=2", true, 1.0});
  }
  ComparisonOptions options;
  options.baseline = "B";
  absl::StatusOr<ComparisonReport> report = CompareMethods(trials, options);
  ASSERT_TRUE(report.ok()) << report.status();
  // k=1: A vs B and C vs B; k=2: A vs B (C has no trial there).
  ASSERT_EQ(report->comparisons.size(), 3u);
  EXPECT_EQ(report->comparisons[0].method, "A");
  EXPECT_EQ(report->comparisons[1].method, "C");
  EXPECT_EQ(report->comparisons[2].variant, "k=2");
  for (const Comparison& c : report->comparisons) EXPECT_EQ(c.other, "B");
  // Holm over k=1's two comparisons: A's McNemar p doubled (the smaller).
  const Comparison& a = report->comparisons[0];
  const Comparison& cc = report->comparisons[1];
  EXPECT_DOUBLE_EQ(a.success.mcnemar_p_holm, std::min(1.0, 2 * a.success.mcnemar_p));
  EXPECT_DOUBLE_EQ(cc.success.mcnemar_p_holm, std::max(a.success.mcnemar_p_holm, cc.success.mcnemar_p));
  // k=2 is its own family: identical outcomes, p = 1 unadjusted and adjusted.
  EXPECT_DOUBLE_EQ(report->comparisons[2].success.mcnemar_p_holm, 1.0);
  EXPECT_DOUBLE_EQ(report->comparisons[2].wilcoxon.p, 1.0);
  EXPECT_EQ(report->comparisons[2].wilcoxon.zeros, 8);
}

TEST(CompareMethodsTest, RefusesAnUnknownBaselineNamingTheMethods) {
  ComparisonOptions options;
  options.baseline = "PILCO";
  absl::StatusOr<ComparisonReport> report = CompareMethods(TwoMethods(), options);
  ASSERT_FALSE(report.ok());
  EXPECT_EQ(report.status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_NE(report.status().message().find("'PILCO'"), std::string::npos);
  EXPECT_NE(report.status().message().find("A, B"), std::string::npos);
  options.baseline = "";
  options.alpha = 1.5;
  EXPECT_FALSE(CompareMethods(TwoMethods(), options).ok());
}

TEST(CompareMethodsTest, CountsDuplicateSeedsAndSkipsLoneMethods) {
  std::vector<CompletedTrial> trials = {{"A", "1", "", true, 1.0}, {"A", "1", "", false, 2.0}};
  absl::StatusOr<ComparisonReport> report = CompareMethods(trials, {});
  ASSERT_TRUE(report.ok());
  EXPECT_EQ(report->duplicate_trials, 1);
  EXPECT_TRUE(report->comparisons.empty());
}

// The verdicts the CLI and the dashboard print (issue 29): which test, which
// method, at alpha after Holm.
TEST(CompareMethodsTest, VerdictsNameTheFavouredMethodOnlyWhenSignificant) {
  Comparison c;
  c.method = "RP";
  c.other = "TP";
  c.success.mcnemar_p_holm = 0.01;
  c.success.difference = 0.3;  // RP succeeded more often
  EXPECT_EQ(SuccessVerdict(c, 0.05), "RP better");
  c.success.difference = -0.3;
  EXPECT_EQ(SuccessVerdict(c, 0.05), "TP better");
  EXPECT_EQ(SuccessVerdict(c, 0.01), "no evidence");  // p must be below alpha
  c.success.mcnemar_p_holm = std::nan("");
  EXPECT_EQ(SuccessVerdict(c, 0.05), "no evidence");
  c.wilcoxon_p_holm = 0.02;
  c.wilcoxon.rank_biserial = -0.8;  // RP's costs lower
  EXPECT_EQ(CostVerdict(c, 0.05), "RP better");
  c.wilcoxon.rank_biserial = 0.8;
  EXPECT_EQ(CostVerdict(c, 0.05), "TP better");
  c.wilcoxon.rank_biserial = 0;
  EXPECT_EQ(CostVerdict(c, 0.05), "no evidence");
  c.wilcoxon.rank_biserial = -0.8;
  c.wilcoxon_p_holm = 0.2;
  EXPECT_EQ(CostVerdict(c, 0.05), "no evidence");
}

}  // namespace hypothesis_tests_test
}  // namespace totalgrad::results
