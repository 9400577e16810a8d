// The dashboard's documents (server/dashboard/dashboard_data.h): the
// estimated time to finish, and the success table and the paper's Table 1
// over a real store, named as the CLI names them (results/).
#include "server/dashboard/dashboard_data.h"

#include <gtest/gtest.h>

#include <filesystem>
#include <set>

#include "core/learner/checkpoint.h"
#include "core/learner/trial.h"
#include "results/stats.h"
#include "results/table1.h"
#include "server/storage/sqlite_store.h"
#include "tests/service/service_testutil.h"

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

// A store holding completed trials: sweeps of RP jobs on (tip, k = 1) under
// the paper's protocol (but for `particles`), each with its success.
class DashboardStoreTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = testing::MakeTempDir();
    absl::StatusOr<std::unique_ptr<storage::SqliteStore>> store =
        storage::SqliteStore::Open(dir_ + "/store.db");
    ASSERT_TRUE(store.ok()) << store.status();
    store_ = std::move(*store);
  }
  void TearDown() override {
    store_.reset();
    if (!HasFailure()) std::filesystem::remove_all(dir_);
  }
  // Sweep `name` of RP seeds first_seed.., one job per entry of `successes`,
  // run to completion (two episodes each).
  void CompletedSweep(const std::string& name, int first_seed, const std::vector<bool>& successes,
                      const std::string& particles = "300") {
    storage::NewSweep sweep = testing::MakeSweep(name, static_cast<int>(successes.size()), 2,
                                                 "hash-" + name);
    for (size_t i = 0; i < sweep.jobs.size(); ++i) {
      storage::NewJob& job = sweep.jobs[i];
      job.seed = std::to_string(first_seed + static_cast<int>(i));
      job.options = {{"method", "RP"}, {"seed", job.seed}, {"scene", "cartpole-swingup"},
                     {"cost", "tip"}, {"noise_k", "1"}, {"episodes", "15"},
                     {"policy_steps", "600"}, {"particles", particles},
                     {"eval_rollouts", "30"}, {"threshold", "15"}};
    }
    bool created = false;
    ASSERT_TRUE(store_->CreateSweep(sweep, kNow, &created).ok());
    absl::StatusOr<std::vector<storage::JobRecord>> jobs = store_->ListJobs({name, {}, 0, 1000});
    ASSERT_TRUE(jobs.ok()) << jobs.status();
    for (size_t i = 0; i < jobs->size(); ++i) {
      const int64_t id = (*jobs)[i].id;
      ASSERT_TRUE(store_->StartAttempt({id, 1}, testing::MakeWorker("w1"), kNow, kNow + 90'000).ok());
      CompleteAttempt(id, successes[i], successes[i] ? 5 : 30);
    }
  }
  // Ends attempt 1 of job `id` (leased to "w1") completed, with episodes 0 and 1.
  void CompleteAttempt(int64_t id, bool success, double final_eval_cost) {
    storage::AttemptEnd end;
    end.key = {id, 1};
    end.worker_id = "w1";
    end.attempt_state = storage::AttemptState::kCompleted;
    end.job_state = storage::JobState::kCompleted;
    end.results.episodes = {testing::MakeEpisode(0), testing::MakeEpisode(1)};
    end.totals.episodes = 2;
    end.success = success;
    end.final_eval_cost = final_eval_cost;
    end.now_ms = kNow;
    absl::StatusOr<storage::EndOutcome> ended = store_->EndAttempt(end);
    ASSERT_TRUE(ended.ok()) << ended.status();
  }

  std::string dir_;
  std::unique_ptr<storage::SqliteStore> store_;
};

// One name per statistic: the success table's cells carry exactly the keys
// of `results table -f json` (results::TableCellFields()).
TEST_F(DashboardStoreTest, TheSuccessTableIsNamedAsTheClisTable) {
  CompletedSweep("s", 1, {true, true, false});
  DashboardData data(store_.get(), {});
  absl::StatusOr<nlohmann::json> sweep = data.Sweep("s", kNow);
  ASSERT_TRUE(sweep.ok()) << sweep.status();
  const nlohmann::json& cells = (*sweep)["table"]["cells"];
  ASSERT_EQ(cells.size(), 1u);
  std::set<std::string> keys, names;
  for (auto it = cells[0].begin(); it != cells[0].end(); ++it) keys.insert(it.key());
  for (const auto& field : results::TableCellFields()) names.insert(field.name);
  EXPECT_EQ(keys, names);
  EXPECT_EQ(cells[0]["successes"], 2);
  EXPECT_NEAR(cells[0]["wilson95_low"].get<double>(), results::WilsonInterval(2, 3).first, 1e-15);
  EXPECT_FALSE(cells[0].contains("wilson_low"));
}

// Keeps the last checkpoint a trial gives.
class LastCheckpoint : public learner::TrialObserver {
 public:
  void OnEpisode(const learner::EpisodeResult&) override {}
  bool WantsCheckpoints() override { return true; }
  void OnCheckpoint(const learner::TrialCheckpoint& checkpoint) override { last = checkpoint; }
  learner::TrialCheckpoint last;
};

// The sweep page's final trajectories decode a completed trial's final
// checkpoint once, not on every refresh: after `sweep prune --completed`
// removed it, the same DashboardData still answers from what it decoded
// (within the cache's minute), while a fresh one finds nothing to show.
TEST_F(DashboardStoreTest, FinalTrajectoriesDecodeEachCompletedCheckpointOnce) {
  learner::TrialOptions options;
  for (const auto& [key, value] : std::vector<std::pair<std::string, std::string>>{
           {"method", "RP"}, {"episodes", "1"}, {"policy_steps", "2"}, {"particles", "8"},
           {"eval_rollouts", "3"}, {"horizon", "10"}, {"basis_functions", "8"},
           {"gp_iterations", "10"}, {"predicted_cost_particles", "10"}, {"seed", "3"},
           {"verdict_rollouts", "3"}, {"verdict_hold_seconds", "0.2"}}) {
    ASSERT_TRUE(learner::SetTrialOption(key, value, &options).ok()) << key;
  }
  LastCheckpoint observer;
  absl::StatusOr<learner::TrialSummary> trial = learner::RunTrial(options, &observer);
  ASSERT_TRUE(trial.ok()) << trial.status();

  bool created = false;
  ASSERT_TRUE(store_->CreateSweep(testing::MakeSweep("s", 1, 2), kNow, &created).ok());
  absl::StatusOr<std::vector<storage::JobRecord>> jobs = store_->ListJobs({"s", {}, 0, 10});
  ASSERT_TRUE(jobs.ok()) << jobs.status();
  const int64_t id = jobs->front().id;
  ASSERT_TRUE(store_->StartAttempt({id, 1}, testing::MakeWorker("w1"), kNow, kNow + 90'000).ok());
  ASSERT_TRUE(store_
                  ->StoreCheckpoint({id, 1}, "w1",
                                    {observer.last.episode, learner::kCheckpointFormatVersion,
                                     learner::EncodeCheckpoint(observer.last)},
                                    kNow)
                  .ok());
  CompleteAttempt(id, false, 5);

  DashboardData data(store_.get(), {});
  absl::StatusOr<nlohmann::json> first = data.FinalTrajectories("s");
  ASSERT_TRUE(first.ok()) << first.status();
  ASSERT_EQ((*first)["trials"].size(), 1u) << first->dump();
  EXPECT_EQ((*first)["trials"][0]["goal_distance"].size(), 11u);  // H = 10 steps and the start
  EXPECT_EQ((*first)["without"], 0);

  ASSERT_TRUE(store_->PruneCheckpoints("s", storage::PruneScope::kCompleted, kNow).ok());
  absl::StatusOr<nlohmann::json> again = data.FinalTrajectories("s");
  ASSERT_TRUE(again.ok()) << again.status();
  EXPECT_EQ(*again, *first);
  DashboardData fresh(store_.get(), {});
  absl::StatusOr<nlohmann::json> pruned = fresh.FinalTrajectories("s");
  ASSERT_TRUE(pruned.ok()) << pruned.status();
  EXPECT_TRUE((*pruned)["trials"].empty());
  EXPECT_EQ((*pruned)["without"], 1);
}

TEST_F(DashboardStoreTest, Table1PoolsSweepsMarksTheProtocolAndRefusesASeedTwice) {
  CompletedSweep("first", 1, {true, false, true});
  CompletedSweep("second", 4, {true}, /*particles=*/"50");
  CompletedSweep("again", 2, {true});  // seed 2 of RP on (tip, k = 1), as in "first"
  DashboardData data(store_.get(), {});
  absl::StatusOr<nlohmann::json> grid = data.Table1({"first", "second"});
  ASSERT_TRUE(grid.ok()) << grid.status();
  EXPECT_EQ((*grid)["methods"], nlohmann::json(results::Table1Methods()));
  ASSERT_EQ((*grid)["rows"].size(), 4u);
  EXPECT_EQ((*grid)["rows"][3]["label"], "tip, k = 1");
  ASSERT_EQ((*grid)["cells"].size(), 32u);
  const nlohmann::json& rp = (*grid)["cells"][3 * 8 + 1];  // (tip, k = 1), RP
  EXPECT_EQ(rp["method"], "RP");
  EXPECT_EQ(rp["trials"], 4);
  EXPECT_EQ(rp["successes"], 3);
  EXPECT_EQ(rp["paper_success_rate"], 0.15);
  EXPECT_EQ(rp["paper_in_interval"], "no");  // 3 of 4: [0.301, 0.954]
  EXPECT_EQ(rp["off_protocol_trials"], 1);
  EXPECT_EQ(rp["protocol_differences"], "particles = 50 (paper 300)");
  EXPECT_EQ(rp["sweeps"], nlohmann::json::array({"first", "second"}));
  std::set<std::string> keys, names;
  for (auto it = rp.begin(); it != rp.end(); ++it) keys.insert(it.key());
  for (const auto& field : results::Table1CellFields()) names.insert(field.name);
  EXPECT_EQ(keys, names);

  absl::StatusOr<nlohmann::json> twice = data.Table1({"first", "again"});
  ASSERT_EQ(twice.status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_NE(twice.status().message().find("seed 2 of RP in (tip, k = 1) is in sweep first"),
            std::string::npos) << twice.status();
  EXPECT_EQ(data.Table1({"first", "nope"}).status().code(), absl::StatusCode::kNotFound);
  EXPECT_EQ(data.Table1({}).status().code(), absl::StatusCode::kInvalidArgument);
}

}  // namespace
}  // namespace totalgrad::dashboard
