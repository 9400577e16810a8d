// Threshold sensitivity, the paper's planned paired comparisons and the
// power table (results/table1_claims.h) on hand-made trials, against counts
// and values worked by hand.
#include "results/table1_claims.h"

#include <gtest/gtest.h>

#include <cmath>

#include "results/hypothesis_tests.h"
#include "results/paired_intervals.h"

namespace totalgrad::results {
namespace table1_claims_test {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();
constexpr size_t kTip001 = 2, kTip1 = 3;

CompletedTrial Trial(const std::string& method, int seed, double final_cost,
                  const std::string& noise_k = "1", double held_fraction = kNaN) {
  CompletedTrial trial;
  trial.sweep = "s";
  trial.job_id = seed;
  trial.method = method;
  trial.seed = std::to_string(seed);
  trial.final_eval_cost = final_cost;
  trial.success = final_cost < 15;  // the trial's own rule at threshold 15
  trial.held_fraction = held_fraction;
  trial.options = PaperProtocol();
  trial.options.emplace_back("cost", "tip");
  trial.options.emplace_back("noise_k", noise_k);
  return trial;
}

Table1 Compute(const std::vector<CompletedTrial>& trials) {
  absl::StatusOr<Table1> table = ComputeTable1(trials);
  EXPECT_TRUE(table.ok()) << table.status();
  return *table;
}

TEST(ThresholdSensitivityTest, CountsEachThresholdAndNamesTheVerdictsThatChange) {
  // PILCO, tip k = 1: costs 10.8, 13.4, 14.7, 15.53, 16.9, 22.
  // Below 13: 1; 14: 2; 15: 3 (stored); 16: 4; 17: 5.
  const Table1 table = Compute({Trial("PILCO", 10, 10.8), Trial("PILCO", 11, 13.4),
                                Trial("PILCO", 12, 14.7), Trial("PILCO", 14, 15.53),
                                Trial("PILCO", 13, 16.9), Trial("PILCO", 15, 22.0),
                                Trial("PILCO", 16, kNaN)});
  const std::vector<ThresholdRate> rates =
      ThresholdSensitivity(table, DefaultSensitivityThresholds());
  ASSERT_EQ(rates.size(), 5u);  // one cell x five thresholds
  const int expected_successes[] = {1, 2, 3, 4, 5};
  for (size_t i = 0; i < rates.size(); ++i) {
    EXPECT_EQ(rates[i].method, "PILCO");
    EXPECT_EQ(rates[i].cost, "tip");
    EXPECT_EQ(rates[i].noise_k, 1);
    EXPECT_EQ(rates[i].threshold, DefaultSensitivityThresholds()[i]);
    EXPECT_EQ(rates[i].success.trials, 6) << "the trial without a cost is left out";
    EXPECT_EQ(rates[i].success.successes, expected_successes[i]);
    EXPECT_DOUBLE_EQ(rates[i].success.rate, expected_successes[i] / 6.0);
  }
  EXPECT_EQ(rates[2].changed, 0);
  EXPECT_EQ(rates[2].changed_trials, "");
  EXPECT_EQ(rates[0].changed, 2);
  EXPECT_EQ(rates[0].changed_trials,
            "seed 11: 13.40 succeeds -> fails; seed 12: 14.70 succeeds -> fails");
  EXPECT_EQ(rates[4].changed_trials,
            "seed 13: 16.90 fails -> succeeds; seed 14: 15.53 fails -> succeeds");
  // Wilson 95% of 3/6 (z = 1.959964): centre (0.5 + z^2/12) / (1 + z^2/6) = 0.5,
  // half-width z sqrt(0.25/6 + z^2/144) / (1 + z^2/6) = 0.312384.
  EXPECT_NEAR(rates[2].success.low, 0.18761631, 1e-8);
  EXPECT_NEAR(rates[2].success.high, 0.81238369, 1e-8);
}

TEST(CompareClaimsTest, PairsBySeedWithinARowAndHolmAdjustsWithinIt) {
  // Tip, k = 1: GTP and PILCO at seeds 10-15 (seed 15 of PILCO missing, so
  // 5 pairs), TP at seeds 10-12.
  //   seed:     10     11     12     13     14
  //   GTP:     12.0   13.0   16.0   14.0   12.5   (success: y y n y y)
  //   PILCO:   11.0   15.5   14.0   14.5   13.5   (success: y n y y y)
  // success pairs: both 3 (10, 13, 14), GTP only 1 (11), PILCO only 1 (12).
  // cost differences GTP - PILCO: 1.0, -2.5, 2.0, -0.5, -1.0.
  std::vector<CompletedTrial> trials = {
      Trial("GTP", 10, 12.0, "1", 0.9),   Trial("PILCO", 10, 11.0, "1", 0.8),
      Trial("GTP", 11, 13.0, "1", 0.7),   Trial("PILCO", 11, 15.5, "1", 0.2),
      Trial("GTP", 12, 16.0, "1", 0.1),   Trial("PILCO", 12, 14.0, "1", 0.6),
      Trial("GTP", 13, 14.0, "1", 0.4),   Trial("PILCO", 13, 14.5, "1"),
      Trial("GTP", 14, 12.5, "1", 0.95),  Trial("PILCO", 14, 13.5, "1", 0.3),
      Trial("GTP", 15, 12.0, "1"),        Trial("TP", 10, 11.0, "1"),
      Trial("TP", 11, 20.0, "1"),         Trial("TP", 12, 12.0, "1"),
      Trial("GTP", 10, 30.0, "0.01"),     Trial("PILCO", 10, 10.0, "0.01"),
  };
  const std::vector<ClaimComparison> claims = CompareClaims(Compute(trials));
  ASSERT_EQ(claims.size(), Table1PlannedComparisons().size());
  const ClaimComparison* gtp_pilco = nullptr;
  const ClaimComparison* tp_gtp = nullptr;
  const ClaimComparison* low_noise_gtp_pilco = nullptr;
  for (const ClaimComparison& claim : claims) {
    if (claim.noise_k == 1 && claim.method == "GTP" && claim.other == "PILCO") gtp_pilco = &claim;
    if (claim.noise_k == 1 && claim.method == "TP" && claim.other == "GTP") tp_gtp = &claim;
    if (claim.noise_k == 0.01 && claim.method == "GTP") low_noise_gtp_pilco = &claim;
  }
  ASSERT_NE(gtp_pilco, nullptr);
  ASSERT_NE(tp_gtp, nullptr);
  ASSERT_NE(low_noise_gtp_pilco, nullptr);

  EXPECT_EQ(gtp_pilco->cost, "tip");
  EXPECT_EQ(gtp_pilco->success.pairs, 5);
  EXPECT_EQ(gtp_pilco->success.both, 3);
  EXPECT_EQ(gtp_pilco->success.method_only, 1);
  EXPECT_EQ(gtp_pilco->success.other_only, 1);
  EXPECT_EQ(gtp_pilco->success.neither, 0);
  const RateDifferenceInterval expected = NewcombePairedInterval({3, 1, 1, 0});
  EXPECT_DOUBLE_EQ(gtp_pilco->success.difference, 0);
  EXPECT_DOUBLE_EQ(gtp_pilco->success.difference95_low, expected.low);
  EXPECT_DOUBLE_EQ(gtp_pilco->success.difference95_high, expected.high);
  EXPECT_DOUBLE_EQ(gtp_pilco->success.mcnemar_p, 1.0);

  // Verdicts (held >= 0.5) where both were classified: seeds 10 (y, y),
  // 11 (y, n), 12 (n, y), 14 (y, n): 4 pairs, GTP only 2, PILCO only 1.
  EXPECT_EQ(gtp_pilco->verdict.pairs, 4);
  EXPECT_EQ(gtp_pilco->verdict.method_only, 2);
  EXPECT_EQ(gtp_pilco->verdict.other_only, 1);
  EXPECT_DOUBLE_EQ(gtp_pilco->verdict.difference, 0.25);

  // Walsh averages of (1.0, -2.5, 2.0, -0.5, -1.0), 15 of them; the median
  // (8th smallest) is -0.25. n = 5 reaches no 95% rank: [min, max].
  EXPECT_EQ(gtp_pilco->cost_pairs, 5);
  EXPECT_DOUBLE_EQ(gtp_pilco->cost_shift, -0.25);
  EXPECT_DOUBLE_EQ(gtp_pilco->cost_shift95_low, -2.5);
  EXPECT_DOUBLE_EQ(gtp_pilco->cost_shift95_high, 2.0);
  EXPECT_DOUBLE_EQ(gtp_pilco->wilcoxon_p,
                   WilcoxonSignedRank({1.0, -2.5, 2.0, -0.5, -1.0}).p);

  // TP vs GTP: seeds 10-12: TP y n y, GTP y y n: one discordant pair each way.
  EXPECT_EQ(tp_gtp->success.pairs, 3);
  EXPECT_EQ(tp_gtp->success.method_only, 1);
  EXPECT_EQ(tp_gtp->success.other_only, 1);
  EXPECT_EQ(tp_gtp->verdict.pairs, 0) << "TP's trials were not classified";
  EXPECT_TRUE(std::isnan(tp_gtp->verdict.difference));
  EXPECT_TRUE(std::isnan(tp_gtp->verdict.mcnemar_p_holm));

  // Holm within the tip, k = 1 row: two comparisons, each test its own family.
  const std::vector<double> wilcoxon_holm = HolmAdjust({gtp_pilco->wilcoxon_p, tp_gtp->wilcoxon_p});
  EXPECT_DOUBLE_EQ(gtp_pilco->wilcoxon_p_holm, wilcoxon_holm[0]);
  EXPECT_DOUBLE_EQ(tp_gtp->wilcoxon_p_holm, wilcoxon_holm[1]);
  // The k = 0.01 row is its own family: one pair, GTP failed, PILCO did not.
  EXPECT_EQ(low_noise_gtp_pilco->success.pairs, 1);
  EXPECT_EQ(low_noise_gtp_pilco->success.other_only, 1);
  EXPECT_DOUBLE_EQ(low_noise_gtp_pilco->success.mcnemar_p_holm, 1.0);
  EXPECT_DOUBLE_EQ(low_noise_gtp_pilco->cost_shift, 20.0);
}

TEST(CompareClaimsTest, AComparisonWithoutPairsIsNaNAndOutOfTheFamily) {
  const std::vector<ClaimComparison> claims =
      CompareClaims(Compute({Trial("GTP", 10, 12.0), Trial("PILCO", 11, 12.0)}));
  for (const ClaimComparison& claim : claims) {
    EXPECT_EQ(claim.success.pairs, 0);
    EXPECT_TRUE(std::isnan(claim.success.difference));
    EXPECT_TRUE(std::isnan(claim.success.mcnemar_p_holm));
    EXPECT_TRUE(std::isnan(claim.cost_shift));
  }
}

TEST(PairedPowerTableTest, TenPairsNeedSixDiscordantPairsAllOneWay) {
  // McNemar at n discordant pairs all one way: p = 2 / 2^n; 2/32 = 0.0625
  // >= 0.05, 2/64 = 0.03125 < 0.05: six.
  const std::vector<PowerEntry> table = PairedPowerTable(10);
  ASSERT_EQ(table.size(), 19u);  // 10 one-sided differences, 9 with 0.1 the other way
  for (const PowerEntry& entry : table) EXPECT_EQ(entry.min_one_sided_discordant, 6);
  // A true difference of 1.0 (every seed: only `method` succeeds): power 1.
  EXPECT_DOUBLE_EQ(table[9].difference, 1.0);
  EXPECT_NEAR(table[9].power, 1.0, 1e-12);
  // Difference 0.5 with no discordance the other way: P(Binomial(10, 0.5)
  // >= 6) = 386/1024, since every outcome with 6+ one-way discordant pairs
  // and none the other way rejects, and none with fewer does.
  EXPECT_DOUBLE_EQ(table[4].method_only_rate, 0.5);
  EXPECT_NEAR(table[4].power, 386.0 / 1024, 1e-12);
  for (const PowerEntry& entry : table) {
    EXPECT_LE(entry.power_holm2, entry.power + 1e-15);
    EXPECT_LE(entry.power_holm4, entry.power_holm2 + 1e-15);
  }
}

}  // namespace table1_claims_test
}  // namespace totalgrad::results
