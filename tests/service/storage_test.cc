// SqliteStore on real files: schema and pragmas, idempotent sweep creation,
// fencing of stale attempts, duplicate episodes, completion checks, restart
// persistence, backup, export.
#include "server/storage/sqlite_store.h"

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>

#include "tests/service/service_testutil.h"

namespace totalgrad::storage {
namespace {

using ::totalgrad::testing::MakeEpisode;
using ::totalgrad::testing::MakeSweep;
using ::totalgrad::testing::MakeTempDir;
using ::totalgrad::testing::MakeWorker;

constexpr int64_t kNow = 1'000'000;

class StorageTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = MakeTempDir();
    path_ = dir_ + "/store.db";
    auto store = SqliteStore::Open(path_);
    ASSERT_TRUE(store.ok()) << store.status();
    store_ = std::move(*store);
  }
  void TearDown() override {
    store_.reset();
    if (!HasFailure()) std::filesystem::remove_all(dir_);
  }
  void Reopen() {
    store_.reset();
    auto store = SqliteStore::Open(path_);
    ASSERT_TRUE(store.ok()) << store.status();
    store_ = std::move(*store);
  }
  // Creates a sweep and leases its first job to worker "w1" as attempt 1.
  int64_t CreateAndLease(const std::string& name, int jobs = 1, int episodes = 3) {
    bool created = false;
    auto sweep = store_->CreateSweep(MakeSweep(name, jobs, episodes), kNow, &created);
    EXPECT_TRUE(sweep.ok()) << sweep.status();
    auto jobs_list = store_->ListJobs({name, {}, 0, 1000});
    EXPECT_TRUE(jobs_list.ok());
    const int64_t job_id = jobs_list->front().id;
    TG_EXPECT_OK(store_->StartAttempt({job_id, 1}, MakeWorker("w1"), kNow, kNow + 90'000));
    return job_id;
  }

  std::string dir_;
  std::string path_;
  std::unique_ptr<SqliteStore> store_;
};

TEST_F(StorageTest, OpensWithWalFullSyncForeignKeysAndBusyTimeout) {
  TG_ASSERT_OK_AND_ASSIGN(std::string settings, store_->DescribeSettings());
  EXPECT_EQ(settings, "journal_mode=wal synchronous=2 foreign_keys=1 busy_timeout=5000");
}

TEST_F(StorageTest, CreateSweepIsIdempotentForTheSameSpec) {
  bool created = false;
  TG_ASSERT_OK_AND_ASSIGN(SweepRecord first, store_->CreateSweep(MakeSweep("s", 4, 3), kNow, &created));
  EXPECT_TRUE(created);
  EXPECT_EQ(first.jobs_total, 4);
  EXPECT_EQ(first.jobs_queued, 4);
  EXPECT_EQ(first.episodes_expected, 12);
  TG_ASSERT_OK_AND_ASSIGN(SweepRecord again, store_->CreateSweep(MakeSweep("s", 4, 3), kNow + 5, &created));
  EXPECT_FALSE(created);
  EXPECT_EQ(again.id, first.id);
  EXPECT_EQ(again.jobs_total, 4);
  TG_ASSERT_OK_AND_ASSIGN(auto sweeps, store_->ListSweeps());
  EXPECT_EQ(sweeps.size(), 1u);
}

TEST_F(StorageTest, CreateSweepRefusesADifferentSpecUnderATakenName) {
  bool created = false;
  TG_ASSERT_OK(store_->CreateSweep(MakeSweep("s", 2, 3, "hash-a"), kNow, &created));
  auto other = store_->CreateSweep(MakeSweep("s", 5, 3, "hash-b"), kNow, &created);
  EXPECT_EQ(other.status().code(), absl::StatusCode::kAlreadyExists) << other.status();
  EXPECT_FALSE(created);
  TG_ASSERT_OK_AND_ASSIGN(SweepRecord kept, store_->GetSweep("s"));
  EXPECT_EQ(kept.jobs_total, 2);
}

TEST_F(StorageTest, NamesWithQuotesAreStoredVerbatim) {
  const std::string name = "x'); DROP TABLE jobs; --";
  bool created = false;
  TG_ASSERT_OK(store_->CreateSweep(MakeSweep(name, 1, 2), kNow, &created));
  TG_ASSERT_OK_AND_ASSIGN(SweepRecord sweep, store_->GetSweep(name));
  EXPECT_EQ(sweep.name, name);
  TG_ASSERT_OK_AND_ASSIGN(auto jobs, store_->ListJobs({"", {}, 0, 10}));
  EXPECT_EQ(jobs.size(), 1u);
}

TEST_F(StorageTest, StartAttemptIsACompareAndSet) {
  const int64_t job = CreateAndLease("s");
  auto again = store_->StartAttempt({job, 1}, MakeWorker("w2"), kNow, kNow + 1);
  EXPECT_EQ(again.code(), absl::StatusCode::kFailedPrecondition) << again;
  auto skip = store_->StartAttempt({job, 3}, MakeWorker("w2"), kNow, kNow + 1);
  EXPECT_EQ(skip.code(), absl::StatusCode::kFailedPrecondition) << skip;
  TG_ASSERT_OK_AND_ASSIGN(JobRecord record, store_->GetJob(job));
  EXPECT_EQ(record.state, JobState::kRunning);
  EXPECT_EQ(record.attempts, 1);
  EXPECT_EQ(record.worker_id, "w1");
}

TEST_F(StorageTest, RepeatedEpisodesAreNoOpsAndKeepTheFirstValues) {
  const int64_t job = CreateAndLease("s");
  TG_ASSERT_OK_AND_ASSIGN(int stored,
                          store_->StoreEpisodes({job, 1}, "w1", {MakeEpisode(0, 5), MakeEpisode(1, 6)},
                                                kNow, std::nullopt));
  EXPECT_EQ(stored, 2);
  TG_ASSERT_OK_AND_ASSIGN(stored, store_->StoreEpisodes({job, 1}, "w1",
                                                        {MakeEpisode(1, 99), MakeEpisode(2, 7)},
                                                        kNow, std::nullopt));
  EXPECT_EQ(stored, 3);
  std::vector<EpisodeRowRecord> rows;
  TG_ASSERT_OK(store_->ExportEpisodes("s", false, 100, [&](std::vector<EpisodeRowRecord> batch) {
    rows.insert(rows.end(), batch.begin(), batch.end());
    return absl::OkStatus();
  }));
  ASSERT_EQ(rows.size(), 3u);
  EXPECT_EQ(rows[1].episode.real_cost, 6);  // not 99
}

TEST_F(StorageTest, MissingValuesRoundTripAsNaN) {
  const int64_t job = CreateAndLease("s");
  TG_ASSERT_OK(store_->StoreEpisodes({job, 1}, "w1", {MakeEpisode(0, 5)}, kNow, std::nullopt));
  std::vector<EpisodeRowRecord> rows;
  TG_ASSERT_OK(store_->ExportEpisodes("s", false, 100, [&](std::vector<EpisodeRowRecord> batch) {
    rows = std::move(batch);
    return absl::OkStatus();
  }));
  ASSERT_EQ(rows.size(), 1u);
  EXPECT_EQ(rows[0].episode.real_cost, 5);
  EXPECT_TRUE(std::isnan(rows[0].episode.eval_cost_mean));
}

TEST_F(StorageTest, OutOfRangeEpisodeStoresNothingFromTheCall) {
  const int64_t job = CreateAndLease("s", 1, 3);
  auto result = store_->StoreEpisodes({job, 1}, "w1", {MakeEpisode(0), MakeEpisode(3)}, kNow,
                                      std::nullopt);
  EXPECT_EQ(result.status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_NE(result.status().message().find("episode 3"), std::string::npos) << result.status();
  TG_ASSERT_OK_AND_ASSIGN(JobRecord record, store_->GetJob(job));
  EXPECT_EQ(record.episodes_stored, 0);  // episode 0 was rolled back with the call
}

TEST_F(StorageTest, StaleAttemptAndForeignWorkerAreAborted) {
  const int64_t job = CreateAndLease("s");
  AttemptEnd lost;
  lost.key = {job, 1};
  lost.worker_id = "w1";
  lost.attempt_state = AttemptState::kLeaseLost;
  lost.job_state = JobState::kQueued;
  lost.lost_leases_delta = 1;
  lost.now_ms = kNow;
  TG_ASSERT_OK(store_->EndAttempt(lost));
  TG_ASSERT_OK(store_->StartAttempt({job, 2}, MakeWorker("w2"), kNow, kNow + 90'000));

  auto late = store_->StoreEpisodes({job, 1}, "w1", {MakeEpisode(0)}, kNow, kNow + 1);
  EXPECT_EQ(late.status().code(), absl::StatusCode::kAborted) << late.status();
  auto foreign = store_->StoreEpisodes({job, 2}, "w1", {MakeEpisode(0)}, kNow, kNow + 1);
  EXPECT_EQ(foreign.status().code(), absl::StatusCode::kAborted) << foreign.status();
  AttemptEnd late_complete;
  late_complete.key = {job, 1};
  late_complete.worker_id = "w1";
  late_complete.attempt_state = AttemptState::kCompleted;
  late_complete.job_state = JobState::kCompleted;
  late_complete.episodes_total = 1;
  late_complete.now_ms = kNow;
  EXPECT_EQ(store_->EndAttempt(late_complete).status().code(), absl::StatusCode::kAborted);

  TG_ASSERT_OK_AND_ASSIGN(JobRecord record, store_->GetJob(job));
  EXPECT_EQ(record.state, JobState::kRunning);
  EXPECT_EQ(record.attempts, 2);
  EXPECT_EQ(record.lost_leases, 1);
  EXPECT_EQ(record.episodes_stored, 0);
}

TEST_F(StorageTest, CompletionNamesMissingEpisodesAndChangesNothing) {
  const int64_t job = CreateAndLease("s", 1, 4);
  TG_ASSERT_OK(store_->StoreEpisodes({job, 1}, "w1", {MakeEpisode(0), MakeEpisode(3)}, kNow,
                                     std::nullopt));
  AttemptEnd end;
  end.key = {job, 1};
  end.worker_id = "w1";
  end.attempt_state = AttemptState::kCompleted;
  end.job_state = JobState::kCompleted;
  end.episodes_total = 4;
  end.success = true;
  end.final_eval_cost = 3;
  end.now_ms = kNow;
  auto incomplete = store_->EndAttempt(end);
  EXPECT_EQ(incomplete.status().code(), absl::StatusCode::kFailedPrecondition);
  EXPECT_NE(incomplete.status().message().find("episodes 1,2 of 0..3"), std::string::npos)
      << incomplete.status();
  TG_ASSERT_OK_AND_ASSIGN(JobRecord still, store_->GetJob(job));
  EXPECT_EQ(still.state, JobState::kRunning);

  end.episodes = {MakeEpisode(1), MakeEpisode(2)};
  TG_ASSERT_OK_AND_ASSIGN(EndOutcome outcome, store_->EndAttempt(end));
  EXPECT_EQ(outcome, EndOutcome::kApplied);
  TG_ASSERT_OK_AND_ASSIGN(outcome, store_->EndAttempt(end));
  EXPECT_EQ(outcome, EndOutcome::kAlreadyEnded);
  TG_ASSERT_OK_AND_ASSIGN(JobRecord done, store_->GetJob(job));
  EXPECT_EQ(done.state, JobState::kCompleted);
  EXPECT_EQ(done.completed_attempt, 1);
  EXPECT_TRUE(done.success);
  EXPECT_EQ(done.final_eval_cost, 3);
  TG_ASSERT_OK_AND_ASSIGN(auto results, store_->ListTrialResults("s"));
  ASSERT_EQ(results.size(), 1u);
  EXPECT_EQ(results[0].episodes, 4);
}

TEST_F(StorageTest, CancelSweepCancelsQueuedAndRunningJobs) {
  const int64_t running = CreateAndLease("s", 3, 2);
  TG_ASSERT_OK(store_->SetSweepState("s", SweepState::kCancelled, kNow));
  TG_ASSERT_OK_AND_ASSIGN(SweepRecord sweep, store_->GetSweep("s"));
  EXPECT_EQ(sweep.state, SweepState::kCancelled);
  EXPECT_EQ(sweep.jobs_cancelled, 3);
  EXPECT_TRUE(sweep.finished());
  // The running attempt stays open until the worker answers the CANCEL.
  TG_ASSERT_OK_AND_ASSIGN(auto attempts, store_->ListAttempts(running));
  ASSERT_EQ(attempts.size(), 1u);
  EXPECT_EQ(attempts[0].state, AttemptState::kRunning);
  TG_ASSERT_OK_AND_ASSIGN(auto candidates, store_->ListClaimCandidates(10));
  EXPECT_TRUE(candidates.empty());
  EXPECT_EQ(store_->SetSweepState("nope", SweepState::kPaused, kNow).code(),
            absl::StatusCode::kNotFound);
}

TEST_F(StorageTest, RetryOnlyFailedOrCancelledJobs) {
  const int64_t job = CreateAndLease("s", 1, 2);
  EXPECT_EQ(store_->RetryJob(job, kNow).code(), absl::StatusCode::kFailedPrecondition);
  AttemptEnd fail;
  fail.key = {job, 1};
  fail.worker_id = "w1";
  fail.attempt_state = AttemptState::kFailed;
  fail.job_state = JobState::kFailed;
  fail.failures_delta = 3;
  fail.error = "boom";
  fail.now_ms = kNow;
  TG_ASSERT_OK(store_->EndAttempt(fail));
  TG_ASSERT_OK(store_->RetryJob(job, kNow));
  TG_ASSERT_OK_AND_ASSIGN(JobRecord record, store_->GetJob(job));
  EXPECT_EQ(record.state, JobState::kQueued);
  EXPECT_EQ(record.failures, 0);
  EXPECT_EQ(record.attempts, 1);
  EXPECT_EQ(record.last_error, "boom");
  EXPECT_EQ(store_->RetryJob(12345, kNow).code(), absl::StatusCode::kNotFound);
}

TEST_F(StorageTest, ExtendOpenLeasesMovesOnlyEarlierExpiries) {
  const int64_t job = CreateAndLease("s");
  TG_ASSERT_OK_AND_ASSIGN(int extended, store_->ExtendOpenLeases(kNow + 500'000, kNow));
  EXPECT_EQ(extended, 1);
  TG_ASSERT_OK_AND_ASSIGN(auto expired, store_->ListExpiredLeases(kNow + 400'000));
  EXPECT_TRUE(expired.empty());
  TG_ASSERT_OK_AND_ASSIGN(expired, store_->ListExpiredLeases(kNow + 600'000));
  ASSERT_EQ(expired.size(), 1u);
  EXPECT_EQ(expired[0], (LeaseKey{job, 1}));
}

TEST_F(StorageTest, EverythingAcknowledgedSurvivesReopen) {
  const int64_t job = CreateAndLease("s", 2, 3);
  TG_ASSERT_OK(store_->StoreEpisodes({job, 1}, "w1", {MakeEpisode(0), MakeEpisode(1)}, kNow,
                                     std::nullopt));
  Reopen();
  TG_ASSERT_OK_AND_ASSIGN(JobRecord record, store_->GetJob(job));
  EXPECT_EQ(record.state, JobState::kRunning);
  EXPECT_EQ(record.episodes_stored, 2);
  EXPECT_EQ(record.options.size(), 3u);
  EXPECT_EQ(record.options[0], (std::pair<std::string, std::string>("method", "RP")));
  TG_ASSERT_OK_AND_ASSIGN(SweepRecord sweep, store_->GetSweep("s"));
  EXPECT_EQ(sweep.jobs_total, 2);
  EXPECT_EQ(sweep.episodes_stored, 2);
}

TEST_F(StorageTest, RefusesAForeignDatabase) {
  store_.reset();
  const std::string other = dir_ + "/other.db";
  {
    auto db = internal::Db::Open(other, true, 1000);
    ASSERT_TRUE(db.ok());
    TG_ASSERT_OK(db->Exec("CREATE TABLE t(x)"));
  }
  auto opened = SqliteStore::Open(other);
  EXPECT_EQ(opened.status().code(), absl::StatusCode::kFailedPrecondition) << opened.status();
  const std::string text = dir_ + "/text.db";
  std::ofstream(text) << "this is not a database, just some text that is long enough......";
  auto garbage = SqliteStore::Open(text);
  EXPECT_FALSE(garbage.ok());
  EXPECT_EQ(garbage.status().code(), absl::StatusCode::kDataLoss) << garbage.status();
}

TEST_F(StorageTest, BackupIsAConsistentOpenableCopy) {
  const int64_t job = CreateAndLease("s", 2, 3);
  TG_ASSERT_OK(store_->StoreEpisodes({job, 1}, "w1", {MakeEpisode(0)}, kNow, std::nullopt));
  const std::string copy = dir_ + "/backup.db";
  TG_ASSERT_OK_AND_ASSIGN(int64_t bytes, store_->Backup(copy));
  EXPECT_GT(bytes, 0);
  EXPECT_EQ(store_->Backup(copy).status().code(), absl::StatusCode::kAlreadyExists);
  // The original keeps working after the backup.
  TG_ASSERT_OK(store_->StoreEpisodes({job, 1}, "w1", {MakeEpisode(1)}, kNow, std::nullopt));
  auto restored = SqliteStore::Open(copy);
  ASSERT_TRUE(restored.ok()) << restored.status();
  TG_ASSERT_OK_AND_ASSIGN(JobRecord record, (*restored)->GetJob(job));
  EXPECT_EQ(record.episodes_stored, 1);
  TG_ASSERT_OK_AND_ASSIGN(SweepRecord sweep, (*restored)->GetSweep("s"));
  EXPECT_EQ(sweep.jobs_total, 2);
}

TEST_F(StorageTest, ExportShowsTheCountingAttemptUnlessAllAreAsked) {
  const int64_t job = CreateAndLease("s", 1, 2);
  TG_ASSERT_OK(store_->StoreEpisodes({job, 1}, "w1", {MakeEpisode(0, 1)}, kNow, std::nullopt));
  AttemptEnd fail;
  fail.key = {job, 1};
  fail.worker_id = "w1";
  fail.attempt_state = AttemptState::kFailed;
  fail.job_state = JobState::kQueued;
  fail.failures_delta = 1;
  fail.error = "non-finite";
  fail.now_ms = kNow;
  TG_ASSERT_OK(store_->EndAttempt(fail));
  TG_ASSERT_OK(store_->StartAttempt({job, 2}, MakeWorker("w2"), kNow, kNow + 1000));
  TG_ASSERT_OK(store_->StoreEpisodes({job, 2}, "w2", {MakeEpisode(0, 2), MakeEpisode(1, 3)}, kNow,
                                     std::nullopt));
  auto collect = [&](bool all) {
    std::vector<EpisodeRowRecord> rows;
    EXPECT_TRUE(store_->ExportEpisodes("s", all, 1, [&](std::vector<EpisodeRowRecord> batch) {
      EXPECT_EQ(batch.size(), 1u);
      rows.insert(rows.end(), batch.begin(), batch.end());
      return absl::OkStatus();
    }).ok());
    return rows;
  };
  EXPECT_EQ(collect(false).size(), 2u);
  EXPECT_EQ(collect(true).size(), 3u);
  EXPECT_EQ(store_->ExportEpisodes("missing", false, 1, [](auto) { return absl::OkStatus(); }).code(),
            absl::StatusCode::kNotFound);
}

}  // namespace
}  // namespace totalgrad::storage
