// io::EpisodeToJson: `totalgrad trial --json`'s line (the episode's record, then its details).
#include "io/episode_json.h"

#include <gtest/gtest.h>

#include <limits>

namespace totalgrad::io {
namespace episode_json_test {

// PILCO episodes carry the model's predicted cost mean and std per step; the
// JSON line prints them (NaN as null), and episodes without them print none.
TEST(EpisodeToJson, PrintsPilcosPerStepPredictionsOnlyWhenPresent) {
  learner::EpisodeResult result;
  result.episode = 3;
  result.real_cost = 12.5;
  result.predicted_cost = 0.75;
  result.predicted_cost_mean_per_step = Vector{{0.5, 0.25}};
  result.predicted_cost_std_per_step = Vector{{0.125, std::numeric_limits<double>::quiet_NaN()}};
  const nlohmann::json j = EpisodeToJson(result);
  ASSERT_TRUE(j.contains("predicted_cost_mean_per_step"));
  EXPECT_EQ(j["predicted_cost_mean_per_step"], nlohmann::json::array({0.5, 0.25}));
  ASSERT_EQ(j["predicted_cost_std_per_step"].size(), 2u);
  EXPECT_EQ(j["predicted_cost_std_per_step"][0], 0.125);
  EXPECT_TRUE(j["predicted_cost_std_per_step"][1].is_null());
  EXPECT_EQ(j["episode"], 3);
  EXPECT_EQ(j["real_cost"], 12.5);

  learner::EpisodeResult particle;
  particle.episode = 3;
  const nlohmann::json k = EpisodeToJson(particle);
  EXPECT_FALSE(k.contains("predicted_cost_mean_per_step"));
  EXPECT_FALSE(k.contains("predicted_cost_std_per_step"));
  EXPECT_TRUE(k["real_cost"].is_null());  // NaN
}

// The GP hyperparameters have the layout of the stored details_json (an
// object of arrays; docs/results_schema.md), not one object per output.
TEST(EpisodeToJson, GpIsAnObjectOfArraysAsStored) {
  learner::EpisodeResult result;
  result.hyperparameters.log_lengthscales = RowMatrix{{1.0, 2.0, 3.0}, {4.0, 5.0, 6.0}};
  result.hyperparameters.log_signal_std = Vector{{0.5, 0.25}};
  result.hyperparameters.log_noise_std = Vector{{-1.0, -2.0}};
  const nlohmann::json j = EpisodeToJson(result);
  ASSERT_TRUE(j.contains("gp"));
  ASSERT_TRUE(j["gp"].is_object());
  EXPECT_EQ(j["gp"]["log_lengthscales"], nlohmann::json::parse("[[1.0, 2.0, 3.0], [4.0, 5.0, 6.0]]"));
  EXPECT_EQ(j["gp"]["log_signal_std"], nlohmann::json::array({0.5, 0.25}));
  EXPECT_EQ(j["gp"]["log_noise_std"], nlohmann::json::array({-1.0, -2.0}));
  EXPECT_FALSE(EpisodeToJson(learner::EpisodeResult{}).contains("gp"));
}

}  // namespace episode_json_test
}  // namespace totalgrad::io
