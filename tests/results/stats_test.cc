// The statistics behind the results views (results/stats.h): Wilson
// intervals, quantiles, the Table 1 and curve grouping.
#include "results/stats.h"

#include <gtest/gtest.h>

#include <cmath>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "io/record_format.h"

namespace totalgrad::results {
namespace stats_test {

TEST(WilsonIntervalTest, MatchesPublishedValues) {
  // Reference values as given by statsmodels' proportion_confint(method="wilson").
  auto [low, high] = WilsonInterval(5, 10);
  EXPECT_NEAR(low, 0.2366, 1e-4);
  EXPECT_NEAR(high, 0.7634, 1e-4);
  std::tie(low, high) = WilsonInterval(74, 100);
  EXPECT_NEAR(low, 0.6463, 1e-4);
  EXPECT_NEAR(high, 0.8160, 1e-4);
}

TEST(WilsonIntervalTest, StaysInsideTheUnitIntervalAtTheEdges) {
  auto [low, high] = WilsonInterval(0, 3);
  EXPECT_EQ(low, 0.0);
  EXPECT_NEAR(high, 0.5615, 1e-4);
  std::tie(low, high) = WilsonInterval(3, 3);
  EXPECT_NEAR(low, 0.4385, 1e-4);
  EXPECT_EQ(high, 1.0);
  std::tie(low, high) = WilsonInterval(0, 0);
  EXPECT_EQ(low, 0.0);
  EXPECT_EQ(high, 1.0);
}

TEST(WilsonRateTest, KeepsRateAndIntervalThoseOfItsCounts) {
  WilsonRate rate;
  EXPECT_EQ(rate.trials, 0);
  EXPECT_TRUE(std::isnan(rate.rate) && std::isnan(rate.low) && std::isnan(rate.high));
  for (bool succeeded : {true, false, true, true, false, true, false, true, false, false}) {
    rate.Add(succeeded);
  }
  EXPECT_EQ(rate.trials, 10);
  EXPECT_EQ(rate.successes, 5);
  EXPECT_EQ(rate.rate, 0.5);
  EXPECT_NEAR(rate.low, 0.2366, 1e-4);  // statsmodels, as above
  EXPECT_NEAR(rate.high, 0.7634, 1e-4);
}

// A record that holds WilsonRates is written flat, under the names every
// results record uses, and read back into its nested members.
TEST(WilsonRateTest, ItsFieldsAreWrittenAndReadFlat) {
  TableCell cell;
  cell.method = "GTP";
  cell.variant = "k=1";
  cell.success.Add(true);
  cell.success.Add(false);
  cell.median_final_cost = 14.5;
  cell.held.Add(true);
  const nlohmann::ordered_json json = io::RecordToJson(TableCellFields(), cell);
  std::vector<std::string> keys;
  for (const auto& [key, value] : json.items()) keys.push_back(key);
  EXPECT_EQ(keys, (std::vector<std::string>{"method", "variant", "trials", "successes",
                                            "success_rate", "wilson95_low", "wilson95_high",
                                            "median_final_cost", "classified", "held", "held_rate",
                                            "held_wilson95_low", "held_wilson95_high"}));
  EXPECT_EQ(json["trials"], 2);
  EXPECT_EQ(json["successes"], 1);
  EXPECT_EQ(json["success_rate"], 0.5);
  // Wilson at 1 of 2: 0.5 -+ z/(1 + z^2/2) sqrt(1/8 + z^2/16); 1 of 1: low
  // 1/(1 + z^2).
  EXPECT_NEAR(json["wilson95_low"].get<double>(), 0.0945312, 1e-6);
  EXPECT_NEAR(json["wilson95_high"].get<double>(), 0.9054688, 1e-6);
  EXPECT_EQ(json["classified"], 1);
  EXPECT_EQ(json["held"], 1);
  EXPECT_EQ(json["held_rate"], 1.0);
  EXPECT_NEAR(json["held_wilson95_low"].get<double>(), 0.2065493, 1e-6);
  EXPECT_EQ(json["held_wilson95_high"], 1.0);
  TableCell read;
  ASSERT_TRUE(io::RecordFromJson(TableCellFields(), json, "", &read).ok());
  EXPECT_EQ(read.success.trials, 2);
  EXPECT_EQ(read.success.successes, 1);
  EXPECT_EQ(read.success.low, cell.success.low);
  EXPECT_EQ(read.held.trials, 1);
  EXPECT_EQ(read.held.high, 1.0);
  EXPECT_EQ(read.median_final_cost, 14.5);
}

TEST(QuantileTest, InterpolatesLinearlyBetweenOrderStatistics) {
  EXPECT_EQ(Quantile({3, 1, 2, 4}, 0.5), 2.5);
  EXPECT_EQ(Quantile({3, 1, 2, 4}, 0.25), 1.75);
  EXPECT_EQ(Quantile({3, 1, 2, 4}, 1.0), 4);
  EXPECT_EQ(Quantile({7}, 0.75), 7);
  EXPECT_TRUE(std::isnan(Quantile({}, 0.5)));
}

TEST(SuccessTableTest, GroupsByMethodAndVariantInFirstAppearanceOrder) {
  // (method, seed, variant, success, final_eval_cost)
  const std::vector<CompletedTrial> rows = {
      {"RP", "1", "k=1", true, 10}, {"LR", "1", "k=1", false, 30}, {"RP", "2", "k=1", false, 20},
      {"RP", "1", "k=0.01", true, 5}, {"RP", "3", "k=1", true, 12}};
  const std::vector<TableCell> table = SuccessTable(rows);
  ASSERT_EQ(table.size(), 3u);
  EXPECT_EQ(table[0].method, "RP");
  EXPECT_EQ(table[0].variant, "k=1");
  EXPECT_EQ(table[0].success.trials, 3);
  EXPECT_EQ(table[0].success.successes, 2);
  EXPECT_NEAR(table[0].success.rate, 2.0 / 3, 1e-12);
  // No trial has a rollout verdict: the held rate and its bounds are blank,
  // not the interval [0, 1].
  EXPECT_EQ(table[0].held.trials, 0);
  EXPECT_TRUE(std::isnan(table[0].held.rate) && std::isnan(table[0].held.low) &&
              std::isnan(table[0].held.high));
  EXPECT_EQ(table[0].median_final_cost, 12);
  EXPECT_EQ(table[1].variant, "k=0.01");
  EXPECT_EQ(table[2].method, "LR");
}

TEST(CurvesTest, MedianAndQuartilesPerEpisodeSkippingMissingValues) {
  const std::vector<EpisodeValue> values = {
      {"RP", "", 1, 10}, {"RP", "", 1, 20}, {"RP", "", 1, 30}, {"RP", "", 2, 5},
      {"RP", "", 0, std::nan("")}};
  const std::vector<CurvePoint> curves = Curves(values);
  ASSERT_EQ(curves.size(), 2u);
  EXPECT_EQ(curves[0].episode, 1);
  EXPECT_EQ(curves[0].values.trials, 3);
  EXPECT_EQ(curves[0].values.q25, 15);
  EXPECT_EQ(curves[0].values.median, 20);
  EXPECT_EQ(curves[0].values.q75, 25);
  // Mean 20; sample variance ((-10)^2 + 0 + 10^2) / 2 = 100; SE sqrt(100 / 3).
  EXPECT_EQ(curves[0].values.mean, 20);
  EXPECT_DOUBLE_EQ(curves[0].values.standard_error, std::sqrt(100.0 / 3.0));
  // One trial: a mean, no standard error.
  EXPECT_EQ(curves[1].values.mean, 5);
  EXPECT_TRUE(std::isnan(curves[1].values.standard_error));
}

// The paper's Figure 3 "top runs": per method and variant, the k runs with
// the lowest final value (a run's last episode with a value), ties by id.
TEST(CurvesTest, BestRunsKeepsTheKRunsOfLowestFinalValuePerMethodAndVariant) {
  const double nan = std::nan("");
  std::vector<EpisodeValue> values;
  const auto run = [&](const std::string& method, const std::string& variant, int64_t trial,
                       std::vector<double> costs) {
    for (size_t e = 0; e < costs.size(); ++e)
      values.push_back({method, variant, static_cast<int>(e + 1), costs[e], trial});
  };
  run("RP", "k=1", 1, {30, 12});        // final 12
  run("RP", "k=1", 2, {10, 25});        // final 25 (its early 10 does not count)
  run("RP", "k=1", 3, {28, 9, nan});    // final 9 (episode 3 has no value)
  run("RP", "k=1", 4, {20, 12});        // final 12, ties with run 1: id decides
  run("TP", "k=1", 5, {40, 40});        // alone in its cell
  run("RP", "k=0.01", 6, {50, 50});     // another variant
  run("RP", "k=1", 7, {nan, nan});      // no value: dropped
  const std::vector<EpisodeValue> best = BestRuns(values, 2);
  std::vector<int64_t> trials;
  for (const EpisodeValue& v : best)
    if (trials.empty() || trials.back() != v.trial) trials.push_back(v.trial);
  EXPECT_EQ(trials, (std::vector<int64_t>{1, 3, 5, 6}));
  EXPECT_EQ(best.size(), 2u + 3u + 2u + 2u);  // the kept runs' values, in order
  const std::vector<CurvePoint> curves = Curves(best);
  // RP k=1 episode 2 over runs 1 and 3: median of {12, 9}.
  for (const CurvePoint& p : curves)
    if (p.method == "RP" && p.variant == "k=1" && p.episode == 2) EXPECT_EQ(p.values.median, 10.5);
  EXPECT_EQ(BestRuns(values, 10).size(), values.size() - 2);  // all but run 7's two NaNs
}

}  // namespace stats_test
}  // namespace totalgrad::results
