// The dashboard's estimated time to finish (server/dashboard/dashboard_data.h).
#include "server/dashboard/dashboard_data.h"

#include <gtest/gtest.h>

namespace totalgrad::dashboard {
namespace {

constexpr int64_t kNow = 1'700'000'000'000;

TEST(EstimateFinishTest, WeighsMissingEpisodesByTheTimeOfTheirIndex) {
  // Job A has episodes 0 (1 s) and 1 (2 s) of 4; job B none of 4. Unseen
  // indices 2 and 3 take index 1's time: A needs 2 + 2, B 1 + 2 + 2 + 2.
  const std::vector<RemainingJob> remaining = {{2, 4}, {0, 4}};
  const std::vector<EpisodeWork> episodes = {{0, 1.0, kNow - 30'000}, {1, 2.0, kNow - 10'000}};
  const FinishEstimate e = EstimateFinish(remaining, episodes, kNow, 600'000);
  ASSERT_TRUE(e.known) << e.basis;
  EXPECT_DOUBLE_EQ(e.remaining_work_s, 11.0);
  // 3 s of work in the 30 s since the first episode.
  EXPECT_DOUBLE_EQ(e.throughput, 0.1);
  EXPECT_DOUBLE_EQ(e.seconds, 110.0);
  EXPECT_NE(e.basis.find("6 episodes"), std::string::npos) << e.basis;
}

TEST(EstimateFinishTest, UsesTheMedianPerIndexAndOnlyTheRecentWindowForTheRate) {
  // Index 1 took 1, 2 and 9 s: median 2. Only the episode of the last 60 s
  // counts towards the rate (4 s of work in 60 s).
  const std::vector<RemainingJob> remaining = {{1, 2}};
  const std::vector<EpisodeWork> episodes = {{1, 1.0, kNow - 500'000},
                                             {1, 9.0, kNow - 400'000},
                                             {1, 2.0, kNow - 300'000},
                                             {0, 4.0, kNow - 20'000}};
  const FinishEstimate e = EstimateFinish(remaining, episodes, kNow, 60'000);
  ASSERT_TRUE(e.known) << e.basis;
  EXPECT_DOUBLE_EQ(e.remaining_work_s, 2.0);
  EXPECT_DOUBLE_EQ(e.throughput, 4.0 / 60);
  EXPECT_DOUBLE_EQ(e.seconds, 30.0);
}

TEST(EstimateFinishTest, UnknownWithoutEpisodesOrRecentProgress) {
  EXPECT_FALSE(EstimateFinish({{0, 3}}, {}, kNow, 600'000).known);
  EXPECT_EQ(EstimateFinish({{0, 3}}, {}, kNow, 600'000).basis, "no episode finished yet");
  const FinishEstimate stalled =
      EstimateFinish({{1, 3}}, {{0, 1.0, kNow - 3'600'000}}, kNow, 600'000);
  EXPECT_FALSE(stalled.known);
  EXPECT_NE(stalled.basis.find("no episode stored in the last 10 min"), std::string::npos)
      << stalled.basis;
  EXPECT_FALSE(EstimateFinish({{3, 3}}, {{0, 1.0, kNow}}, kNow, 600'000).known);
}

TEST(EpisodeWorkSecondsTest, SumsTheWallPhasesOrFallsBack) {
  EXPECT_DOUBLE_EQ(EpisodeWorkSeconds(
                       R"({"timing": {"model_wall": 1.5, "model_cpu": 9, "policy_wall": 2,
                                      "evaluation_wall": 0.5}})",
                       7.0),
                   4.0);
  EXPECT_DOUBLE_EQ(EpisodeWorkSeconds("{}", 7.0), 7.0);
  EXPECT_DOUBLE_EQ(EpisodeWorkSeconds("not json", 7.0), 7.0);
}

}  // namespace
}  // namespace totalgrad::dashboard
