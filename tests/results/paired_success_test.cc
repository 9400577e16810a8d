// Paired success comparisons (results/paired_success.h) on hand-counted
// tables, and their fields as one results record writes them.
#include "results/paired_success.h"

#include <gtest/gtest.h>

#include <cmath>
#include <string>
#include <vector>

#include "io/record_format.h"

namespace totalgrad::results {
namespace paired_success_test {

TEST(PairedOutcomesTest, AddCountsEachPairInItsCell) {
  PairedOutcomes outcomes;
  // (first, second): 3 both, 2 first only, 1 second only, 1 neither.
  for (auto [first, second] : std::vector<std::pair<bool, bool>>{
           {true, true}, {true, false}, {true, true}, {false, true},
           {false, false}, {true, false}, {true, true}}) {
    outcomes.Add(first, second);
  }
  EXPECT_EQ(outcomes.both, 3);
  EXPECT_EQ(outcomes.first_only, 2);
  EXPECT_EQ(outcomes.second_only, 1);
  EXPECT_EQ(outcomes.neither, 1);
  EXPECT_EQ(outcomes.pairs(), 7);
}

TEST(PairedSuccessTest, MatchesTheHandWorkedTable) {
  // The table of NewcombePairedInterval's hand-worked case: 10 pairs, both
  // 5, method only 3, other only 1, neither 1. McNemar: 4 discordant pairs,
  // 3 one way: p = 2 * P(X <= 1 | 4, 1/2) = 2 * 5/16 = 0.625.
  const PairedSuccess s = ComparePairedSuccess({5, 3, 1, 1});
  EXPECT_EQ(s.pairs, 10);
  EXPECT_EQ(s.both, 5);
  EXPECT_EQ(s.method_only, 3);
  EXPECT_EQ(s.other_only, 1);
  EXPECT_EQ(s.neither, 1);
  EXPECT_EQ(s.difference, 0.2);  // (3 - 1) / 10, one rounding
  EXPECT_NEAR(s.difference95_low, -0.1675297868156374, 1e-12);
  EXPECT_NEAR(s.difference95_high, 0.507718613018509, 1e-12);
  EXPECT_DOUBLE_EQ(s.mcnemar_p, 0.625);
  EXPECT_EQ(s.mcnemar_p_holm, s.mcnemar_p) << "a family of one until the caller adjusts";
  EXPECT_EQ(s.mcnemar_power, McNemarExactPower(10, 0.3, 0.1));
  EXPECT_LT(ComparePairedSuccess({5, 3, 1, 1}, 0.01).mcnemar_power, s.mcnemar_power)
      << "power falls with alpha";
}

TEST(PairedSuccessTest, NoPairsLeavesTheEstimatesBlank) {
  const PairedSuccess s = ComparePairedSuccess({});
  EXPECT_EQ(s.pairs, 0);
  EXPECT_TRUE(std::isnan(s.difference) && std::isnan(s.difference95_low) &&
              std::isnan(s.difference95_high) && std::isnan(s.mcnemar_power));
  EXPECT_EQ(s.mcnemar_p, 1.0);
}

struct TwoComparisons {
  std::string name;
  PairedSuccess first;
  PairedSuccess second;
};

TEST(PairedSuccessTest, ARecordWritesEachUnderItsNames) {
  record::FieldTable<TwoComparisons> table = {{"name", &TwoComparisons::name}};
  AppendPairedSuccessFields<&TwoComparisons::first>(kPairedSuccessNames, &table);
  AppendPairedSuccessFields<&TwoComparisons::second>(kPairedVerdictNames, &table);
  TwoComparisons record{"x", ComparePairedSuccess({5, 3, 1, 1}), ComparePairedSuccess({0, 2, 0, 0})};
  const nlohmann::ordered_json json = io::RecordToJson(table, record);
  ASSERT_EQ(json.size(), 23u);
  EXPECT_EQ(json["both_succeeded"], 5);
  EXPECT_EQ(json["success_difference"], 0.2);
  EXPECT_EQ(json["verdict_pairs"], 2);
  EXPECT_EQ(json["verdict_both_held"], 0);
  EXPECT_EQ(json["verdict_method_only"], 2);
  EXPECT_EQ(json["verdict_difference"], 1.0);
  EXPECT_EQ(json["verdict_mcnemar_p"], 0.5);
  TwoComparisons read;
  ASSERT_TRUE(io::RecordFromJson(table, json, "", &read).ok());
  EXPECT_EQ(read.first.method_only, 3);
  EXPECT_EQ(read.first.difference95_low, record.first.difference95_low);
  EXPECT_EQ(read.second.mcnemar_power, record.second.mcnemar_power);
}

}  // namespace paired_success_test
}  // namespace totalgrad::results
