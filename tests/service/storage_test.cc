// SqliteStore on real files: schema and pragmas, idempotent sweep creation,
// fencing of stale attempts, duplicate episodes, completion checks, restart
// persistence, backup, export.
#include "server/storage/sqlite_store.h"
#include "server/storage/sqlite_schema.h"

#include <gtest/gtest.h>

#include <unistd.h>

#include <chrono>
#include <cmath>
#include <filesystem>
#include <map>
#include <fstream>
#include <thread>

#include "absl/strings/str_cat.h"
#include "absl/strings/str_join.h"
#include "server/storage/sqlite_internal.h"
#include "tests/service/process_util.h"
#include "tests/service/schema_downgrade.h"
#include "tests/service/service_testutil.h"

namespace totalgrad::storage {
namespace storage_test {

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

  // Ends attempt `key` of worker "w1" as a lost lease; the job is queued again.
  absl::Status LoseLease(const LeaseKey& key) {
    AttemptEnd lost;
    lost.key = key;
    lost.worker_id = "w1";
    lost.attempt_state = AttemptState::kLeaseLost;
    lost.job_state = JobState::kQueued;
    lost.lost_leases_delta = 1;
    lost.now_ms = kNow;
    return store_->EndAttempt(lost).status();
  }

  // Stores episode 0 of `job`'s attempt 1, closes the store and opens the
  // file with a raw connection (to turn it into an older schema).
  void StoreAnEpisodeAndOpenTheFileRaw(int64_t job, std::optional<internal::Db>* db) {
    TG_ASSERT_OK(store_->StoreResults({job, 1}, "w1", {{MakeEpisode(0)}}, kNow, std::nullopt)
                     .status());
    store_.reset();
    auto opened = internal::Db::Open(path_, false, 1000);
    ASSERT_TRUE(opened.ok()) << opened.status();
    db->emplace(std::move(*opened));
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
  // The same sweep under the hash a newer build gives it: recognised.
  NewSweep rehashed = MakeSweep("s", 2, 3, "hash-new");
  rehashed.equivalent_spec_hashes = {"hash-a"};
  TG_ASSERT_OK_AND_ASSIGN(SweepRecord same, store_->CreateSweep(rehashed, kNow, &created));
  EXPECT_FALSE(created);
  EXPECT_EQ(same.spec_hash, "hash-a");
}

// Issue 29: a sweep grown by a build whose defaults differ (a scene's own
// horizon) is refused, naming the job, the key and both values, and nothing
// is added; a key the stored jobs lack (added after they ran) is no change.
TEST_F(StorageTest, GrowSweepRefusesAStoredJobWhoseOptionsResolveDifferently) {
  bool created = false;
  NewSweep first = MakeSweep("grown", 2, 3, "hash-a");
  for (storage::NewJob& job : first.jobs) job.options.emplace_back("horizon", "30");
  TG_ASSERT_OK(store_->CreateSweep(first, kNow, &created));

  NewSweep changed = MakeSweep("grown", 3, 3, "hash-b");
  for (storage::NewJob& job : changed.jobs) job.options.emplace_back("horizon", "40");
  const absl::StatusOr<int> refused = store_->GrowSweep(changed, kNow + 1);
  ASSERT_EQ(refused.status().code(), absl::StatusCode::kFailedPrecondition) << refused.status();
  const std::string message(refused.status().message());
  EXPECT_NE(message.find("job RP seed 1 (noise_k=1) is stored with horizon = 30"), std::string::npos)
      << message;
  EXPECT_NE(message.find("resolves the same job to horizon = 40"), std::string::npos) << message;
  EXPECT_NE(message.find("set horizon = 30 in the sweep file's [protocol]"), std::string::npos)
      << message;
  TG_ASSERT_OK_AND_ASSIGN(SweepRecord kept, store_->GetSweep("grown"));
  EXPECT_EQ(kept.jobs_total, 2);
  EXPECT_EQ(kept.spec_hash, "hash-a");

  NewSweep same = MakeSweep("grown", 3, 3, "hash-c");
  for (storage::NewJob& job : same.jobs) {
    job.options.emplace_back("horizon", "30");
    job.options.emplace_back("a_key_added_later", "1");
  }
  TG_ASSERT_OK_AND_ASSIGN(int added, store_->GrowSweep(same, kNow + 2));
  EXPECT_EQ(added, 1);
  TG_ASSERT_OK_AND_ASSIGN(SweepRecord grown, store_->GetSweep("grown"));
  EXPECT_EQ(grown.jobs_total, 3);
}

// Issue 12.6: a value that breaks a CHECK constraint (the service should
// have refused it first) is an internal error saying so, not ALREADY_EXISTS
// as if the sweep existed; nothing is stored.
TEST_F(StorageTest, ConstraintViolationIsNotReportedAsAlreadyExists) {
  NewSweep sweep = MakeSweep("bad", 1, 3);
  sweep.jobs[0].episodes_expected = 0;  // CHECK(episodes_expected >= 1)
  bool created = false;
  auto refused = store_->CreateSweep(sweep, kNow, &created);
  EXPECT_EQ(refused.status().code(), absl::StatusCode::kInternal) << refused.status();
  EXPECT_NE(refused.status().message().find("should have refused"), std::string::npos)
      << refused.status();
  EXPECT_EQ(store_->GetSweep("bad").status().code(), absl::StatusCode::kNotFound);
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
  TG_ASSERT_OK_AND_ASSIGN(
      ResultTotals stored,
      store_->StoreResults({job, 1}, "w1", {{MakeEpisode(0, 5), MakeEpisode(1, 6)}}, kNow,
                           std::nullopt));
  EXPECT_EQ(stored, (ResultTotals{.episodes = 2}));
  TG_ASSERT_OK_AND_ASSIGN(
      stored, store_->StoreResults({job, 1}, "w1", {{MakeEpisode(1, 99), MakeEpisode(2, 7)}},
                                   kNow, std::nullopt));
  EXPECT_EQ(stored, (ResultTotals{.episodes = 3}));
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
  TG_ASSERT_OK(store_->StoreResults({job, 1}, "w1", {{MakeEpisode(0, 5)}}, kNow, std::nullopt));
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
  auto result = store_->StoreResults({job, 1}, "w1", {{MakeEpisode(0), MakeEpisode(3)}}, kNow,
                                      std::nullopt);
  EXPECT_EQ(result.status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_NE(result.status().message().find("episode 3"), std::string::npos) << result.status();
  TG_ASSERT_OK_AND_ASSIGN(JobRecord record, store_->GetJob(job));
  EXPECT_EQ(record.episodes_stored, 0);  // episode 0 was rolled back with the call
}

TEST_F(StorageTest, StaleAttemptAndForeignWorkerAreAborted) {
  const int64_t job = CreateAndLease("s");
  TG_ASSERT_OK(LoseLease({job, 1}));
  TG_ASSERT_OK(store_->StartAttempt({job, 2}, MakeWorker("w2"), kNow, kNow + 90'000));

  auto late = store_->StoreResults({job, 1}, "w1", {{MakeEpisode(0)}}, kNow, kNow + 1);
  EXPECT_EQ(late.status().code(), absl::StatusCode::kAborted) << late.status();
  auto foreign = store_->StoreResults({job, 2}, "w1", {{MakeEpisode(0)}}, kNow, kNow + 1);
  EXPECT_EQ(foreign.status().code(), absl::StatusCode::kAborted) << foreign.status();
  AttemptEnd late_complete;
  late_complete.key = {job, 1};
  late_complete.worker_id = "w1";
  late_complete.attempt_state = AttemptState::kCompleted;
  late_complete.job_state = JobState::kCompleted;
  late_complete.totals.episodes = 1;
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
  TG_ASSERT_OK(store_->StoreResults({job, 1}, "w1", {{MakeEpisode(0), MakeEpisode(3)}}, kNow,
                                     std::nullopt));
  AttemptEnd end;
  end.key = {job, 1};
  end.worker_id = "w1";
  end.attempt_state = AttemptState::kCompleted;
  end.job_state = JobState::kCompleted;
  end.totals.episodes = 4;
  end.success = true;
  end.final_eval_cost = 3;
  end.now_ms = kNow;
  auto incomplete = store_->EndAttempt(end);
  EXPECT_EQ(incomplete.status().code(), absl::StatusCode::kFailedPrecondition);
  EXPECT_NE(incomplete.status().message().find("episodes 1,2 of 0..3"), std::string::npos)
      << incomplete.status();
  TG_ASSERT_OK_AND_ASSIGN(JobRecord still, store_->GetJob(job));
  EXPECT_EQ(still.state, JobState::kRunning);

  end.results.episodes = {MakeEpisode(1), MakeEpisode(2)};
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

// SQLite's plan of `sql` (EXPLAIN QUERY PLAN) with every parameter 8, its
// steps joined by " | ".
std::string QueryPlan(internal::Db& db, const char* sql, int parameters) {
  absl::StatusOr<internal::Statement> plan =
      internal::Statement::Prepare(db, absl::StrCat("EXPLAIN QUERY PLAN ", sql));
  EXPECT_TRUE(plan.ok()) << plan.status();
  if (!plan.ok()) return "";
  for (int p = 1; p <= parameters; ++p) plan->Bind(p, 8);
  std::vector<std::string> steps;
  while (true) {
    absl::StatusOr<bool> row = plan->Step();
    EXPECT_TRUE(row.ok()) << row.status();
    if (!row.ok() || !*row) break;
    steps.push_back(plan->ColumnText(3));
  }
  return absl::StrJoin(steps, " | ");
}

// Issue 28 item 2: the next job is read from an index, not found by a scan.
// Candidates come sweep by sweep in ordinal order, a paused sweep's queue is
// skipped, and SQLite's plans read the jobs table only through
// jobs_by_state, without sorting (before: one query read and sorted every
// queued job for each lease, "USE TEMP B-TREE FOR ORDER BY").
TEST_F(StorageTest, ClaimCandidatesComeFromTheIndexInOrderWithoutASort) {
  bool created = false;
  TG_ASSERT_OK(store_->CreateSweep(MakeSweep("paused", 3, 1), kNow, &created).status());
  TG_ASSERT_OK(store_->CreateSweep(MakeSweep("second", 4, 1), kNow, &created).status());
  TG_ASSERT_OK(store_->CreateSweep(MakeSweep("third", 2, 1), kNow, &created).status());
  TG_ASSERT_OK(store_->SetSweepState("paused", SweepState::kPaused, kNow));
  TG_ASSERT_OK_AND_ASSIGN(auto second, store_->ListJobs({"second", {}, 0, 1000}));
  TG_ASSERT_OK_AND_ASSIGN(auto third, store_->ListJobs({"third", {}, 0, 1000}));
  TG_ASSERT_OK_AND_ASSIGN(auto candidates, store_->ListClaimCandidates(3));
  ASSERT_EQ(candidates.size(), 3u);
  for (size_t i = 0; i < candidates.size(); ++i) {
    EXPECT_EQ(candidates[i].job_id, second[i].id) << i;
  }
  TG_ASSERT_OK_AND_ASSIGN(candidates, store_->ListClaimCandidates(6));
  ASSERT_EQ(candidates.size(), 6u);
  EXPECT_EQ(candidates[3].job_id, second[3].id);
  EXPECT_EQ(candidates[4].job_id, third[0].id);
  EXPECT_EQ(candidates[5].job_id, third[1].id);

  TG_ASSERT_OK_AND_ASSIGN(internal::Db db, internal::Db::Open(path_, false, 0));
  const auto plan_of = [&](const char* sql, int parameters) {
    return QueryPlan(db, sql, parameters);
  };
  const std::string sweeps = plan_of(internal::ClaimSweepsSql(), 0);
  EXPECT_EQ(sweeps.find("TEMP B-TREE"), std::string::npos) << sweeps;
  EXPECT_NE(sweeps.find("USING COVERING INDEX jobs_by_state (state=? AND sweep_id=?)"),
            std::string::npos)
      << sweeps;
  const std::string jobs = plan_of(internal::ClaimJobsSql(), 2);
  EXPECT_EQ(jobs.find("TEMP B-TREE"), std::string::npos) << jobs;
  EXPECT_NE(jobs.find("SEARCH jobs USING INDEX jobs_by_state (state=? AND sweep_id=?)"),
            std::string::npos)
      << jobs;
}

// An import and a grown sweep read the sweep's jobs once, through an index,
// then each job by its id: a lookup by identity per job scanned the whole
// sweep (a 100,000-job import had not finished after 12 minutes).
TEST_F(StorageTest, ImportAndGrowReadEachJobByItsIdNotByAScan) {
  TG_ASSERT_OK_AND_ASSIGN(internal::Db db, internal::Db::Open(path_, false, 0));
  const std::string ids = QueryPlan(db, internal::SweepJobIdsSql(), 1);
  EXPECT_NE(ids.find("SEARCH jobs USING INDEX"), std::string::npos) << ids;
  EXPECT_NE(ids.find("(sweep_id=?)"), std::string::npos) << ids;
  for (const char* per_job : {internal::ImportedJobStateSql(), internal::StoredJobOptionsSql()}) {
    const std::string plan = QueryPlan(db, per_job, 1);
    EXPECT_NE(plan.find("USING INTEGER PRIMARY KEY (rowid=?)"), std::string::npos) << plan;
    EXPECT_EQ(plan.find("SCAN"), std::string::npos) << plan;
  }
}

// A sweep at its max_concurrent offers no candidates: its long queue would
// otherwise fill the scan and the next sweep's jobs would never be leased.
TEST_F(StorageTest, ASweepAtItsConcurrencyLimitDoesNotHideTheNextSweep) {
  bool created = false;
  NewSweep limited = MakeSweep("limited", 300, 1);
  limited.max_concurrent = 1;
  TG_ASSERT_OK(store_->CreateSweep(limited, kNow, &created).status());
  TG_ASSERT_OK(store_->CreateSweep(MakeSweep("next", 2, 1), kNow, &created).status());
  TG_ASSERT_OK_AND_ASSIGN(auto first, store_->ListJobs({"limited", {}, 0, 1}));
  TG_ASSERT_OK(store_->StartAttempt({first[0].id, 1}, MakeWorker("w1"), kNow, kNow + 90'000));
  TG_ASSERT_OK_AND_ASSIGN(auto next, store_->ListJobs({"next", {}, 0, 1000}));
  TG_ASSERT_OK_AND_ASSIGN(auto candidates, store_->ListClaimCandidates(256));
  ASSERT_EQ(candidates.size(), 2u);
  EXPECT_EQ(candidates[0].job_id, next[0].id);
  EXPECT_EQ(candidates[1].job_id, next[1].id);
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

// Issue 28: the scheduler's light read of a job (GetJobStatus) gives the
// same values as the whole record, through every state a lease passes.
TEST_F(StorageTest, JobStatusIsTheJobRecordsDecisionFields) {
  const auto expect_same = [&](int64_t job) {
    TG_ASSERT_OK_AND_ASSIGN(JobRecord record, store_->GetJob(job));
    TG_ASSERT_OK_AND_ASSIGN(JobStatus status, store_->GetJobStatus(job));
    EXPECT_EQ(status.id, record.id);
    EXPECT_EQ(status.kind, record.kind);
    EXPECT_EQ(status.state, record.state);
    EXPECT_EQ(status.failures, record.failures);
    EXPECT_EQ(status.lost_leases, record.lost_leases);
    EXPECT_EQ(status.max_attempts, record.max_attempts);
    EXPECT_EQ(status.max_lost_leases, record.max_lost_leases);
  };
  const int64_t job = CreateAndLease("s", 1, 2);
  expect_same(job);
  AttemptEnd fail;
  fail.key = {job, 1};
  fail.worker_id = "w1";
  fail.attempt_state = AttemptState::kFailed;
  fail.job_state = JobState::kQueued;
  fail.failures_delta = 1;
  fail.lost_leases_delta = 2;
  fail.error = "boom";
  fail.now_ms = kNow;
  TG_ASSERT_OK(store_->EndAttempt(fail));
  expect_same(job);
  TG_ASSERT_OK_AND_ASSIGN(JobStatus queued, store_->GetJobStatus(job));
  EXPECT_EQ(queued.state, JobState::kQueued);
  EXPECT_EQ(queued.failures, 1);
  EXPECT_EQ(queued.lost_leases, 2);
  EXPECT_GT(queued.max_attempts, 0);
  TG_ASSERT_OK(store_->SetSweepState("s", SweepState::kCancelled, kNow));
  expect_same(job);
  EXPECT_EQ(store_->GetJobStatus(12345).status().code(), absl::StatusCode::kNotFound);
}

// Issue 12.7: trial checkpoints are fenced like episodes, the latest one of
// each attempt is kept (a replayed older one does not replace it), and the
// best of all attempts is what a new attempt resumes from.
TEST_F(StorageTest, CheckpointsAreFencedAndTheLatestIsFoundForResumption) {
  const int64_t job = CreateAndLease("s", 1, 4);
  const std::string bytes("\0binary\xff checkpoint", 21);  // NUL and high bytes survive
  TG_ASSERT_OK(store_->StoreCheckpoint({job, 1}, "w1", {1, 1, bytes}, kNow));
  TG_ASSERT_OK(store_->StoreCheckpoint({job, 1}, "w1", {0, 1, "older"}, kNow));  // a replay
  TG_ASSERT_OK_AND_ASSIGN(auto found, store_->GetCheckpoint(job, 0));
  ASSERT_TRUE(found.has_value());
  EXPECT_EQ(found->key, (LeaseKey{job, 1}));
  EXPECT_EQ(found->checkpoint.episode, 1);
  EXPECT_EQ(found->checkpoint.data, bytes);
  EXPECT_EQ(found->worker_build, "test-worker-build");
  EXPECT_EQ(store_->StoreCheckpoint({job, 1}, "w1", {4, 1, "x"}, kNow).code(),
            absl::StatusCode::kInvalidArgument);  // the trial has episodes 0..3
  EXPECT_EQ(store_->StoreCheckpoint({job, 1}, "w2", {2, 1, "x"}, kNow).code(),
            absl::StatusCode::kAborted);

  AttemptEnd lost;
  lost.key = {job, 1};
  lost.worker_id = "w1";
  lost.attempt_state = AttemptState::kLeaseLost;
  lost.job_state = JobState::kQueued;
  lost.now_ms = kNow;
  TG_ASSERT_OK(store_->EndAttempt(lost));
  EXPECT_EQ(store_->StoreCheckpoint({job, 1}, "w1", {2, 1, "late"}, kNow).code(),
            absl::StatusCode::kAborted);
  TG_ASSERT_OK(store_->StartAttempt({job, 2}, MakeWorker("w2"), kNow, kNow + 90'000));
  TG_ASSERT_OK_AND_ASSIGN(found, store_->GetCheckpoint(job, 0));
  EXPECT_EQ(found->key.attempt, 1);  // what attempt 2 resumes from
  TG_ASSERT_OK(store_->StoreCheckpoint({job, 2}, "w2", {2, 1, "second"}, kNow));
  TG_ASSERT_OK_AND_ASSIGN(found, store_->GetCheckpoint(job, 0));
  EXPECT_EQ(found->key.attempt, 2);
  EXPECT_EQ(found->checkpoint.data, "second");
  TG_ASSERT_OK_AND_ASSIGN(found, store_->GetCheckpoint(job, 1));
  EXPECT_EQ(found->checkpoint.data, bytes);
  TG_ASSERT_OK_AND_ASSIGN(auto attempts, store_->ListAttempts(job));
  EXPECT_EQ(attempts[0].checkpoint_episode, 1);
  EXPECT_EQ(attempts[1].checkpoint_episode, 2);
  TG_ASSERT_OK_AND_ASSIGN(auto none, store_->GetCheckpoint(job + 1000, 0));
  EXPECT_FALSE(none.has_value());
}

// Issue 27: what a sweep's rows take, by what reads its checkpoints, and the
// removal of the checkpoints nothing reads (a completed job's superseded
// attempts'), then of the completed attempts' own; an unfinished job's
// resume point is never removed, and a report changes nothing.
TEST_F(StorageTest, PruneRemovesOnlyWhatItSaysAndReportsTheSizes) {
  const int64_t job = CreateAndLease("s", 2, 2);  // job 1 leased as attempt 1 by "w1"
  TG_ASSERT_OK(store_->StoreCheckpoint({job, 1}, "w1", {0, 1, std::string(100, 'a')}, kNow));
  TG_ASSERT_OK(LoseLease({job, 1}));
  TG_ASSERT_OK(store_->StartAttempt({job, 2}, MakeWorker("w1"), kNow, kNow + 90'000));
  TG_ASSERT_OK(store_->StoreCheckpoint({job, 2}, "w1", {1, 1, std::string(1000, 'b')}, kNow));
  AttemptEnd end;
  end.key = {job, 2};
  end.worker_id = "w1";
  end.attempt_state = AttemptState::kCompleted;
  end.job_state = JobState::kCompleted;
  end.totals.episodes = 2;
  end.results.episodes = {MakeEpisode(0), MakeEpisode(1)};
  end.final_eval_cost = 1;
  end.now_ms = kNow;
  TG_ASSERT_OK(store_->EndAttempt(end).status());
  // The second job: running, with a resume point.
  TG_ASSERT_OK(store_->StartAttempt({job + 1, 1}, MakeWorker("w2"), kNow, kNow + 90'000));
  TG_ASSERT_OK(store_->StoreCheckpoint({job + 1, 1}, "w2", {0, 1, std::string(10, 'c')}, kNow));

  TG_ASSERT_OK_AND_ASSIGN(SweepDiskUse use, store_->PruneCheckpoints("s", PruneScope::kNone, kNow));
  EXPECT_EQ(use.episodes, 2);
  EXPECT_GT(use.episode_details_bytes, 0);
  EXPECT_EQ(use.completed.count, 1);
  EXPECT_EQ(use.completed.bytes, 1000);
  EXPECT_EQ(use.stale.count, 1);
  EXPECT_EQ(use.stale.bytes, 100);
  EXPECT_EQ(use.unfinished.count, 1);
  EXPECT_EQ(use.unfinished.bytes, 10);
  EXPECT_EQ(use.removed.count, 0);
  TG_ASSERT_OK_AND_ASSIGN(use, store_->PruneCheckpoints("s", PruneScope::kNone, kNow));
  EXPECT_EQ(use.stale.count, 1);  // a report removed nothing

  TG_ASSERT_OK_AND_ASSIGN(use, store_->PruneCheckpoints("s", PruneScope::kStale, kNow));
  EXPECT_EQ(use.removed.count, 1);
  EXPECT_EQ(use.removed.bytes, 100);
  TG_ASSERT_OK_AND_ASSIGN(auto final_state, store_->GetCheckpoint(job, 2));
  EXPECT_TRUE(final_state.has_value());
  TG_ASSERT_OK_AND_ASSIGN(auto superseded, store_->GetCheckpoint(job, 1));
  EXPECT_FALSE(superseded.has_value());

  TG_ASSERT_OK_AND_ASSIGN(use, store_->PruneCheckpoints("s", PruneScope::kCompleted, kNow));
  EXPECT_EQ(use.removed.count, 1);
  EXPECT_EQ(use.removed.bytes, 1000);
  TG_ASSERT_OK_AND_ASSIGN(final_state, store_->GetCheckpoint(job, 2));
  EXPECT_FALSE(final_state.has_value());
  TG_ASSERT_OK_AND_ASSIGN(auto resume_point, store_->GetCheckpoint(job + 1, 0));
  ASSERT_TRUE(resume_point.has_value());
  EXPECT_EQ(resume_point->checkpoint.data, std::string(10, 'c'));
  TG_ASSERT_OK_AND_ASSIGN(use, store_->PruneCheckpoints("s", PruneScope::kNone, kNow));
  EXPECT_EQ(use.completed.count + use.stale.count, 0);
  EXPECT_EQ(use.unfinished.count, 1);
  EXPECT_EQ(store_->PruneCheckpoints("nope", PruneScope::kStale, kNow).status().code(),
            absl::StatusCode::kNotFound);
  // A read-only store answers the report.
  TG_ASSERT_OK_AND_ASSIGN(auto read_only, SqliteStore::OpenReadOnly(path_));
  TG_ASSERT_OK_AND_ASSIGN(use, read_only->PruneCheckpoints("s", PruneScope::kNone, kNow));
  EXPECT_EQ(use.unfinished.count, 1);
  EXPECT_EQ(read_only->PruneCheckpoints("s", PruneScope::kStale, kNow).status().code(),
            absl::StatusCode::kFailedPrecondition);
}

// Issue 25: `job supersede` copies a re-run's completed attempt (episodes,
// checkpoint, worker and build) into the superseded job as a new attempt
// that counts from then on, names its origin, keeps the old attempts and
// refuses what is not a re-run of the same trial.
TEST_F(StorageTest, SupersedeCopiesTheRerunsCompletedAttemptAndRefusesOthers) {
  // Completes attempt `attempt` of `job` (worker "w1") with episodes 0..2
  // costing `cost` each and a checkpoint holding `checkpoint`.
  const auto complete = [&](int64_t job, int attempt, double cost, const std::string& checkpoint) {
    TG_ASSERT_OK(store_->StartAttempt({job, attempt}, MakeWorker("w1"), kNow, kNow + 90'000));
    AttemptEnd end;
    end.key = {job, attempt};
    end.worker_id = "w1";
    end.attempt_state = AttemptState::kCompleted;
    end.job_state = JobState::kCompleted;
    end.totals.episodes = 3;
    for (int e = 0; e < 3; ++e) end.results.episodes.push_back(MakeEpisode(e, cost));
    end.results.episodes.back().held_fraction = cost / 100;
    end.checkpoint = Checkpoint{2, 2, checkpoint};
    end.success = cost < 15;
    end.final_eval_cost = cost + 0.5;
    end.now_ms = kNow;
    TG_ASSERT_OK(store_->EndAttempt(end).status());
  };
  bool created = false;
  TG_ASSERT_OK(store_->CreateSweep(MakeSweep("original", 2, 3), kNow, &created).status());
  TG_ASSERT_OK(store_->CreateSweep(MakeSweep("rerun", 2, 3, "other-hash"), kNow, &created).status());
  TG_ASSERT_OK_AND_ASSIGN(auto originals, store_->ListJobs({"original", {}, 0, 10}));
  TG_ASSERT_OK_AND_ASSIGN(auto reruns, store_->ListJobs({"rerun", {}, 0, 10}));
  const int64_t original = originals[0].id, rerun = reruns[0].id;
  // Not completed yet: refused.
  EXPECT_EQ(store_->SupersedeJob(original, rerun, kNow).status().code(),
            absl::StatusCode::kFailedPrecondition);
  complete(original, 1, 29, "old state");
  complete(rerun, 1, 12, "new state");
  complete(originals[1].id, 1, 20, "x");
  complete(reruns[1].id, 1, 20, "y");
  // Another seed, the same sweep, a missing job: refused, nothing changes.
  EXPECT_EQ(store_->SupersedeJob(original, reruns[1].id, kNow).status().code(),
            absl::StatusCode::kFailedPrecondition);
  EXPECT_EQ(store_->SupersedeJob(original, originals[1].id, kNow).status().code(),
            absl::StatusCode::kFailedPrecondition);
  EXPECT_EQ(store_->SupersedeJob(original, 9999, kNow).status().code(),
            absl::StatusCode::kNotFound);
  TG_ASSERT_OK_AND_ASSIGN(JobRecord before, store_->GetJob(original));
  EXPECT_EQ(before.attempts, 1);
  EXPECT_EQ(before.held_fraction, 0.29);

  TG_ASSERT_OK_AND_ASSIGN(const int attempt, store_->SupersedeJob(original, rerun, kNow + 5));
  EXPECT_EQ(attempt, 2);
  TG_ASSERT_OK_AND_ASSIGN(JobRecord after, store_->GetJob(original));
  EXPECT_EQ(after.completed_attempt, 2);
  EXPECT_EQ(after.attempts, 2);
  EXPECT_TRUE(after.success);
  EXPECT_EQ(after.final_eval_cost, 12.5);
  EXPECT_EQ(after.held_fraction, 0.12);
  EXPECT_EQ(after.sweep_name, "original");
  TG_ASSERT_OK_AND_ASSIGN(auto attempts, store_->ListAttempts(original));
  ASSERT_EQ(attempts.size(), 2u);
  EXPECT_EQ(attempts[0].origin, "");
  EXPECT_EQ(attempts[0].state, AttemptState::kCompleted);  // the history stays
  EXPECT_EQ(attempts[1].origin, absl::StrCat("job ", rerun, " attempt 1 of sweep rerun"));
  EXPECT_EQ(attempts[1].worker_build, "test-worker-build");
  EXPECT_EQ(attempts[1].episodes_stored, 3);
  EXPECT_EQ(attempts[1].checkpoint_episode, 2);
  TG_ASSERT_OK_AND_ASSIGN(auto checkpoint, store_->GetCheckpoint(original, 2));
  ASSERT_TRUE(checkpoint.has_value());
  EXPECT_EQ(checkpoint->checkpoint.data, "new state");
  // Every reader counts the copy: the results table and the export.
  TG_ASSERT_OK_AND_ASSIGN(auto results, store_->ListTrialResults("original"));
  ASSERT_EQ(results.size(), 2u);
  EXPECT_EQ(results[0].attempt, 2);
  EXPECT_EQ(results[0].final_eval_cost, 12.5);
  EXPECT_EQ(results[0].held_fraction, 0.12);
  std::vector<EpisodeRowRecord> rows;
  TG_ASSERT_OK(store_->ExportEpisodes("original", false, 100, [&](std::vector<EpisodeRowRecord> batch) {
    for (auto& row : batch) if (row.job_id == original) rows.push_back(std::move(row));
    return absl::OkStatus();
  }));
  ASSERT_EQ(rows.size(), 3u);
  EXPECT_EQ(rows[0].attempt, 2);
  EXPECT_EQ(rows[0].episode.real_cost, 12);
  TG_ASSERT_OK_AND_ASSIGN(auto events, store_->ListEvents(original));
  EXPECT_EQ(events.back().kind, "superseded");
  // Said again (a restart script, an archive that already carries it): no
  // second copy, the same attempt counts.
  TG_ASSERT_OK_AND_ASSIGN(const int again, store_->SupersedeJob(original, rerun, kNow + 6));
  EXPECT_EQ(again, 2);
  TG_ASSERT_OK_AND_ASSIGN(JobRecord unchanged, store_->GetJob(original));
  EXPECT_EQ(unchanged.attempts, 2);
  EXPECT_EQ(unchanged.completed_attempt, 2);
  TG_ASSERT_OK_AND_ASSIGN(auto events_again, store_->ListEvents(original));
  EXPECT_EQ(events_again.size(), events.size());
  // The re-run itself is unchanged.
  TG_ASSERT_OK_AND_ASSIGN(JobRecord source, store_->GetJob(rerun));
  EXPECT_EQ(source.attempts, 1);
  EXPECT_EQ(source.final_eval_cost, 12.5);
}

// Issue 25: an import keeps the archived sweep's submission time, each
// attempt's origin and a kept checkpoint; issue 28: a job completed by an
// attempt that lacks one of its episodes is refused, naming it, and nothing
// of the archive is stored.
TEST_F(StorageTest, ImportKeepsTimesOriginsAndCheckpointsAndRefusesIncompleteTrials) {
  NewSweep sweep = MakeSweep("moved", 1, 3);
  sweep.created_ms = 42;
  ImportedJob job;
  job.record.kind = JobKind::kTrial;
  job.record.method = "RP";
  job.record.seed = "1";
  job.record.variant = "noise_k=1";
  job.record.state = JobState::kCompleted;
  job.record.success = true;
  job.record.final_eval_cost = 2.5;
  job.completed_attempt = 7;
  ImportedAttempt& attempt = job.attempts.emplace_back();
  attempt.attempt = 7;
  attempt.state = AttemptState::kCompleted;
  attempt.worker_id = "w9";
  attempt.started_ms = 100;
  attempt.ended_ms = 200;
  attempt.origin = "job 3 attempt 1 of sweep elsewhere";
  attempt.checkpoint = Checkpoint{2, 2, std::string("\0kept\xff", 6)};
  for (int e = 0; e < 2; ++e) attempt.episodes.emplace_back(MakeEpisode(e), 150 + e);

  // Episode 2 of 0..2 is missing from the completing attempt: refused.
  const auto refused = store_->ImportJobs(sweep, "moved", {job}, "a.json", kNow);
  EXPECT_EQ(refused.status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_NE(refused.status().message().find("holds 2 of its 3 episodes"), std::string::npos)
      << refused.status();
  EXPECT_EQ(store_->GetSweep("moved").status().code(), absl::StatusCode::kNotFound);

  attempt.episodes.emplace_back(MakeEpisode(2), 152);
  TG_ASSERT_OK_AND_ASSIGN(ImportResult result,
                          store_->ImportJobs(sweep, "moved", {job}, "a.json", kNow));
  EXPECT_EQ(result.jobs_imported, 1);
  EXPECT_EQ(result.checkpoints_imported, 1);
  TG_ASSERT_OK_AND_ASSIGN(SweepRecord stored, store_->GetSweep("moved"));
  EXPECT_EQ(stored.created_ms, 42);
  TG_ASSERT_OK_AND_ASSIGN(auto jobs, store_->ListJobs({"moved", {}, 0, 10}));
  TG_ASSERT_OK_AND_ASSIGN(auto attempts, store_->ListAttempts(jobs[0].id));
  ASSERT_EQ(attempts.size(), 1u);
  EXPECT_EQ(attempts[0].origin, "job 3 attempt 1 of sweep elsewhere");
  EXPECT_EQ(attempts[0].checkpoint_episode, 2);
  TG_ASSERT_OK_AND_ASSIGN(auto checkpoint, store_->GetCheckpoint(jobs[0].id, 1));
  ASSERT_TRUE(checkpoint.has_value());
  EXPECT_EQ(checkpoint->checkpoint.data, std::string("\0kept\xff", 6));
  EXPECT_EQ(checkpoint->checkpoint.format_version, 2);
}

TEST_F(StorageTest, ExtendOpenLeasesMovesOnlyEarlierExpiries) {
  const int64_t job = CreateAndLease("s");
  TG_ASSERT_OK_AND_ASSIGN(int extended, store_->ExtendOpenLeases(kNow + 500'000, kNow, "in a test"));
  EXPECT_EQ(extended, 1);
  TG_ASSERT_OK_AND_ASSIGN(auto expired, store_->ListExpiredLeases(kNow + 400'000));
  EXPECT_TRUE(expired.empty());
  TG_ASSERT_OK_AND_ASSIGN(expired, store_->ListExpiredLeases(kNow + 600'000));
  ASSERT_EQ(expired.size(), 1u);
  EXPECT_EQ(expired[0], (LeaseKey{job, 1}));
}

TEST_F(StorageTest, EverythingAcknowledgedSurvivesReopen) {
  const int64_t job = CreateAndLease("s", 2, 3);
  TG_ASSERT_OK(store_->StoreResults({job, 1}, "w1", {{MakeEpisode(0), MakeEpisode(1)}}, kNow,
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
  SqliteStoreOptions init;
  init.init = true;  // --init never touches a foreign file
  for (const SqliteStoreOptions& options : {SqliteStoreOptions{}, init}) {
    auto opened = SqliteStore::Open(other, options);
    EXPECT_EQ(opened.status().code(), absl::StatusCode::kFailedPrecondition) << opened.status();
    EXPECT_NE(opened.status().message().find("not a totalgrad one"), std::string::npos)
        << opened.status();
  }
  const std::string text = dir_ + "/text.db";
  const std::string content = "this is not a database, just some text that is long enough......";
  std::ofstream(text) << content;
  for (const SqliteStoreOptions& options : {SqliteStoreOptions{}, init}) {
    auto garbage = SqliteStore::Open(text, options);
    EXPECT_EQ(garbage.status().code(), absl::StatusCode::kFailedPrecondition) << garbage.status();
    EXPECT_NE(garbage.status().message().find("is not an SQLite database"), std::string::npos)
        << garbage.status();
  }
  EXPECT_EQ(testing::ReadFile(text), content);
}

// Issue 12.4: a second store (a second coordinator) on the same file is
// refused, naming the process that holds it; once that one closes, it opens.
TEST_F(StorageTest, SecondStoreOnTheSameFileIsRefusedNamingTheHolder) {
  auto second = SqliteStore::Open(path_);
  EXPECT_EQ(second.status().code(), absl::StatusCode::kFailedPrecondition) << second.status();
  EXPECT_NE(second.status().message().find("in use by another coordinator"), std::string::npos)
      << second.status();
  EXPECT_NE(second.status().message().find(absl::StrCat("pid ", getpid(), " on host ")),
            std::string::npos)
      << second.status();
  // A consistent read-only copy still works while the file is owned.
  TG_ASSERT_OK(SqliteStore::BackupFile(path_, dir_ + "/copy.db"));
  Reopen();
}

// Issue 12.4: a 0-byte file, or a database that the lock file says existed
// but is gone, is not silently initialised as a new store: --init is needed.
TEST_F(StorageTest, EmptyFileOrDeletedDatabaseNeedsInit) {
  const std::string empty = dir_ + "/empty.db";
  std::ofstream(empty).close();
  auto refused = SqliteStore::Open(empty);
  EXPECT_EQ(refused.status().code(), absl::StatusCode::kFailedPrecondition) << refused.status();
  EXPECT_NE(refused.status().message().find("an empty (0-byte) file"), std::string::npos)
      << refused.status();
  EXPECT_NE(refused.status().message().find("--init"), std::string::npos) << refused.status();
  SqliteStoreOptions init;
  init.init = true;
  TG_ASSERT_OK(SqliteStore::Open(empty, init));

  // The store's own file deleted while it was closed.
  CreateAndLease("s");
  store_.reset();
  for (const char* suffix : {"", "-wal", "-shm"}) std::filesystem::remove(path_ + suffix);
  auto missing = SqliteStore::Open(path_);
  EXPECT_EQ(missing.status().code(), absl::StatusCode::kFailedPrecondition) << missing.status();
  EXPECT_NE(missing.status().message().find("is missing, but its lock file records"),
            std::string::npos)
      << missing.status();
  EXPECT_FALSE(std::filesystem::exists(path_));  // nothing was created
  TG_ASSERT_OK_AND_ASSIGN(store_, SqliteStore::Open(path_, init));
  TG_ASSERT_OK_AND_ASSIGN(auto sweeps, store_->ListSweeps());
  EXPECT_TRUE(sweeps.empty());
}

// Issue 12.4: a file of a newer schema version is refused before anything is
// written to it: not one byte changes (it used to be switched to WAL first).
TEST_F(StorageTest, NewerSchemaIsRefusedAndTheFileIsNotTouched) {
  CreateAndLease("s");
  store_.reset();
  {
    auto db = internal::Db::Open(path_, false, 1000);
    ASSERT_TRUE(db.ok());
    TG_ASSERT_OK(db->Exec("PRAGMA journal_mode=DELETE"));
    TG_ASSERT_OK(db->Exec("PRAGMA user_version=99"));
  }
  ASSERT_FALSE(std::filesystem::exists(path_ + "-wal"));
  const std::string before = testing::ReadFile(path_);
  SqliteStoreOptions init;
  init.init = true;
  for (const SqliteStoreOptions& options : {SqliteStoreOptions{}, init}) {
    auto newer = SqliteStore::Open(path_, options);
    EXPECT_EQ(newer.status().code(), absl::StatusCode::kFailedPrecondition) << newer.status();
    EXPECT_NE(newer.status().message().find("schema version 99"), std::string::npos)
        << newer.status();
  }
  EXPECT_EQ(testing::ReadFile(path_), before);
  EXPECT_FALSE(std::filesystem::exists(path_ + "-wal"));
}

// Issue 12.4: the database file deleted or replaced under an open store:
// writes are refused (Unavailable, so workers keep their results) with the
// problem named, and stay refused.
TEST_F(StorageTest, DeletedOrReplacedDatabaseFileStopsAcknowledgingWrites) {
  TG_ASSERT_OK(store_->CheckWritable());
  for (const char* suffix : {"", "-wal", "-shm"}) std::filesystem::remove(path_ + suffix);
  bool created = false;
  auto submitted = store_->CreateSweep(MakeSweep("after", 1, 2), kNow, &created);
  EXPECT_EQ(submitted.status().code(), absl::StatusCode::kUnavailable) << submitted.status();
  EXPECT_NE(submitted.status().message().find("was deleted"), std::string::npos)
      << submitted.status();
  EXPECT_FALSE(created);
  const absl::Status health = store_->CheckWritable();
  EXPECT_EQ(health.code(), absl::StatusCode::kUnavailable);
  EXPECT_NE(health.message().find("was deleted"), std::string::npos) << health;

  // Replaced: another file now under the same name.
  store_.reset();
  const std::string other_dir = dir_ + "/replaced";
  std::filesystem::create_directories(other_dir);
  const std::string path = other_dir + "/store.db";
  TG_ASSERT_OK_AND_ASSIGN(auto store, SqliteStore::Open(path));
  std::ofstream(other_dir + "/impostor.db") << "x";
  std::filesystem::rename(other_dir + "/impostor.db", path);
  const absl::Status write = store->TouchWorker(MakeWorker("w"), kNow);
  EXPECT_EQ(write.code(), absl::StatusCode::kUnavailable) << write;
  EXPECT_NE(write.message().find("was replaced by another file"), std::string::npos) << write;
  EXPECT_EQ(testing::ReadFile(path), "x");  // the new file was not written to
}

// Issue 12.4: a full disk (here: the database may not grow) fails a commit
// with Unavailable, which workers retry instead of dropping their result
// (it was RESOURCE_EXHAUSTED, which they gave up on), and CheckWritable
// (/healthz) reports it until a commit succeeds again.
TEST_F(StorageTest, FullDiskIsRetryableAndReportedUntilACommitSucceeds) {
  store_.reset();
  const int64_t pages = static_cast<int64_t>(std::filesystem::file_size(path_)) / 4096;
  SqliteStoreOptions limited;
  limited.max_page_count = pages + 2;
  TG_ASSERT_OK_AND_ASSIGN(store_, SqliteStore::Open(path_, limited));
  TG_ASSERT_OK(store_->CheckWritable());
  bool created = false;
  auto big = store_->CreateSweep(MakeSweep("big", 5000, 3), kNow, &created);
  EXPECT_EQ(big.status().code(), absl::StatusCode::kUnavailable) << big.status();
  EXPECT_NE(big.status().message().find("disk is full"), std::string::npos) << big.status();
  const absl::Status health = store_->CheckWritable();
  EXPECT_EQ(health.code(), absl::StatusCode::kUnavailable);
  EXPECT_NE(health.message().find("the last database commit failed"), std::string::npos) << health;
  TG_ASSERT_OK(store_->TouchWorker(MakeWorker("w"), kNow));  // a small commit still fits
  TG_ASSERT_OK(store_->CheckWritable());
}

// Issue 28.4: while another process holds SQLite's write lock (here a
// second connection in BEGIN IMMEDIATE, as the sqlite3 shell would), the
// health check answers Unavailable within a second instead of waiting for
// the lock, also while a write of the coordinator is queued behind it; the
// write fails after busy_timeout naming the lock, and once the lock goes
// both work again with nothing lost.
TEST_F(StorageTest, HeldWriteLockMakesHealthUnavailableAtOnceAndWritesFailNamingIt) {
  SqliteStoreOptions quick;
  quick.busy_timeout_ms = 1500;
  bool created = false;
  TG_ASSERT_OK(store_->CreateSweep(MakeSweep("before", 1, 1), kNow, &created).status());
  store_.reset();
  // Reopened: no commit of this store yet, so the check probes.
  TG_ASSERT_OK_AND_ASSIGN(store_, SqliteStore::Open(path_, quick));
  TG_ASSERT_OK_AND_ASSIGN(internal::Db other, internal::Db::Open(path_, false, 0));
  TG_ASSERT_OK(other.Exec("BEGIN IMMEDIATE"));

  auto took_ms = [](auto since) {
    return std::chrono::duration_cast<std::chrono::milliseconds>(
               std::chrono::steady_clock::now() - since)
        .count();
  };
  auto start = std::chrono::steady_clock::now();
  absl::Status health = store_->CheckWritable();
  EXPECT_LT(took_ms(start), 1000);
  EXPECT_EQ(health.code(), absl::StatusCode::kUnavailable) << health;
  EXPECT_NE(health.message().find("write lock"), std::string::npos) << health;

  // A write waiting for the lock does not hold the check up either.
  absl::Status write;
  std::thread writer([&] { write = store_->TouchWorker(MakeWorker("w"), kNow); });
  std::this_thread::sleep_for(std::chrono::milliseconds(600));
  start = std::chrono::steady_clock::now();
  health = store_->CheckWritable();
  EXPECT_LT(took_ms(start), 1000);
  EXPECT_EQ(health.code(), absl::StatusCode::kUnavailable) << health;
  EXPECT_NE(health.message().find("waited"), std::string::npos) << health;
  writer.join();
  EXPECT_EQ(write.code(), absl::StatusCode::kUnavailable) << write;
  EXPECT_NE(write.message().find("write lock"), std::string::npos) << write;

  TG_ASSERT_OK(other.Exec("ROLLBACK"));
  TG_ASSERT_OK(store_->CheckWritable());
  TG_ASSERT_OK(store_->TouchWorker(MakeWorker("w"), kNow));
  TG_ASSERT_OK(store_->GetSweep("before").status());
}

TEST_F(StorageTest, BackupIsAConsistentOpenableCopy) {
  const int64_t job = CreateAndLease("s", 2, 3);
  TG_ASSERT_OK(store_->StoreResults({job, 1}, "w1", {{MakeEpisode(0)}}, kNow, std::nullopt));
  const std::string copy = dir_ + "/backup.db";
  TG_ASSERT_OK_AND_ASSIGN(int64_t bytes, store_->Backup(copy));
  EXPECT_GT(bytes, 0);
  EXPECT_EQ(store_->Backup(copy).status().code(), absl::StatusCode::kAlreadyExists);
  // The original keeps working after the backup.
  TG_ASSERT_OK(store_->StoreResults({job, 1}, "w1", {{MakeEpisode(1)}}, kNow, std::nullopt));
  auto restored = SqliteStore::Open(copy);
  ASSERT_TRUE(restored.ok()) << restored.status();
  TG_ASSERT_OK_AND_ASSIGN(JobRecord record, (*restored)->GetJob(job));
  EXPECT_EQ(record.episodes_stored, 1);
  TG_ASSERT_OK_AND_ASSIGN(SweepRecord sweep, (*restored)->GetSweep("s"));
  EXPECT_EQ(sweep.jobs_total, 2);
}

TEST_F(StorageTest, ExportShowsTheCountingAttemptUnlessAllAreAsked) {
  const int64_t job = CreateAndLease("s", 1, 2);
  TG_ASSERT_OK(store_->StoreResults({job, 1}, "w1", {{MakeEpisode(0, 1)}}, kNow, std::nullopt));
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
  TG_ASSERT_OK(store_->StoreResults({job, 2}, "w2", {{MakeEpisode(0, 2), MakeEpisode(1, 3)}}, kNow,
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


// ---- study jobs (schema version 2) ----

// A sweep of one trial job and one study job; leases the study job to "w1".
int64_t CreateStudySweepAndLease(SqliteStore* store, const std::string& name) {
  NewSweep sweep = MakeSweep(name, 1, 3);
  NewJob study;
  study.kind = JobKind::kStudy;
  study.method = "study";
  study.seed = "7";
  study.variant = "tiny";
  study.payload = R"({"problem":{"synthetic":{}}})";
  sweep.jobs.push_back(study);
  bool created = false;
  EXPECT_TRUE(store->CreateSweep(sweep, kNow, &created).ok());
  auto jobs = store->ListJobs({name, {}, 0, 1000});
  EXPECT_TRUE(jobs.ok());
  const int64_t job_id = jobs->back().id;
  TG_EXPECT_OK(store->StartAttempt({job_id, 1}, MakeWorker("w1"), kNow, kNow + 90'000));
  return job_id;
}

StudyRows MakeStudyRows() {
  StudyRows rows;
  for (int i = 0; i < 3; ++i) {
    StudyCell c;
    c.index = i;
    c.estimator = i == 2 ? "PILCO" : "RP";
    c.method = c.estimator;
    c.particles = i == 2 ? 0 : 10 * (i + 1);
    c.horizon = 5;
    c.replicates = 4;
    c.nonfinite = i;
    c.errors = 0;
    c.time_min_s = 1e-4 * (i + 1);
    c.time_median_s = 2e-4 * (i + 1);
    c.rel_rmse = 0.1 / 3.0 * (i + 1);  // not exactly representable in decimal
    c.rel_bias = 0.01;
    c.rel_bias_noise = 0.02;
    c.total_variance = 1.5;
    c.cos_mean = 0.9;
    c.objective_mean = 12.25;
    c.ess_mean = kNaN;  // no value
    c.ess_min = kNaN;
    c.k_lr_mean = i == 1 ? 0.5 : kNaN;
    c.reference_agrees = i != 1;
    c.reference_floor = 0.003;
    c.budget_hit = i == 0;
    c.omitted = false;
    c.error = "";
    c.omission_reason = "";
    if (i == 1) c.k_lr_per_step = {0.25, 0.5, 0.75, kNaN, 1.0 / 3.0};
    rows.cells.push_back(c);
  }
  StudyReference r;
  r.index = 0;
  r.horizon = 5;
  r.norm = 2.5;
  r.relative_error = 0.01;
  r.floor = 0.0196;
  r.objective = 12.0;
  r.used = {"RP", "LR(plain,loo)"};
  r.replicates = {4, 3};
  r.agreement_max_z = 1.25;
  r.agreement_mean_z2 = 0.75;
  r.agree = true;
  r.seconds = 0.5;
  r.note = "";
  r.gradient = Vector{{0.1, -0.2, 1.0 / 7.0}};
  r.standard_error = Vector{{0.01, 0.02, 0.03}};
  rows.references.push_back(r);
  return rows;
}

void ExpectSameCell(const StudyCell& a, const StudyCell& b) {
  auto same = [](double x, double y) { return (std::isnan(x) && std::isnan(y)) || x == y; };
  EXPECT_EQ(a.index, b.index);
  EXPECT_EQ(a.estimator, b.estimator);
  EXPECT_EQ(a.method, b.method);
  EXPECT_EQ(a.particles, b.particles);
  EXPECT_EQ(a.horizon, b.horizon);
  EXPECT_EQ(a.replicates, b.replicates);
  EXPECT_EQ(a.nonfinite, b.nonfinite);
  EXPECT_EQ(a.errors, b.errors);
  for (auto [x, y] : {std::pair{a.time_min_s, b.time_min_s}, {a.time_median_s, b.time_median_s},
                      {a.rel_rmse, b.rel_rmse}, {a.rel_bias, b.rel_bias},
                      {a.rel_bias_noise, b.rel_bias_noise}, {a.total_variance, b.total_variance},
                      {a.cos_mean, b.cos_mean}, {a.objective_mean, b.objective_mean},
                      {a.ess_mean, b.ess_mean}, {a.ess_min, b.ess_min}, {a.k_lr_mean, b.k_lr_mean},
                      {a.reference_floor, b.reference_floor}}) {
    EXPECT_TRUE(same(x, y)) << x << " vs " << y << " (cell " << a.index << ")";
  }
  EXPECT_EQ(a.reference_agrees, b.reference_agrees);
  EXPECT_EQ(a.budget_hit, b.budget_hit);
  EXPECT_EQ(a.omitted, b.omitted);
  EXPECT_EQ(study::CellNote(a), study::CellNote(b));
  ASSERT_EQ(a.k_lr_per_step.size(), b.k_lr_per_step.size());
  for (size_t k = 0; k < a.k_lr_per_step.size(); ++k) {
    EXPECT_TRUE(same(a.k_lr_per_step[k], b.k_lr_per_step[k])) << k;
  }
}

TEST_F(StorageTest, StudyRowsRoundTripExactlyAndReplaysAreNoOps) {
  const int64_t job = CreateStudySweepAndLease(store_.get(), "st");
  TG_ASSERT_OK_AND_ASSIGN(JobRecord record, store_->GetJob(job));
  EXPECT_EQ(record.kind, JobKind::kStudy);
  EXPECT_EQ(record.payload, R"({"problem":{"synthetic":{}}})");
  EXPECT_EQ(record.episodes_expected, 0);
  const StudyRows rows = MakeStudyRows();
  // Some rows in one heartbeat, then everything again (a replay after a
  // reconnect), then a changed copy of a stored row: the first values stay.
  StudyRows first;
  first.cells = {rows.cells[0]};
  TG_ASSERT_OK_AND_ASSIGN(ResultTotals stored,
                          store_->StoreResults({job, 1}, "w1", {{}, first}, kNow, kNow + 1));
  EXPECT_EQ(stored, (ResultTotals{.study_cells = 1}));
  TG_ASSERT_OK_AND_ASSIGN(stored,
                          store_->StoreResults({job, 1}, "w1", {{}, rows}, kNow, std::nullopt));
  EXPECT_EQ(stored, (ResultTotals{.study_cells = 3, .study_references = 1}));
  TG_ASSERT_OK_AND_ASSIGN(stored,
                          store_->StoreResults({job, 1}, "w1", {{}, rows}, kNow, std::nullopt));
  EXPECT_EQ(stored, (ResultTotals{.study_cells = 3, .study_references = 1}));
  StudyRows changed = rows;
  changed.cells[0].rel_rmse = 99;
  AttemptEnd end;
  end.key = {job, 1};
  end.worker_id = "w1";
  end.attempt_state = AttemptState::kCompleted;
  end.job_state = JobState::kCompleted;
  end.results.study = changed;  // replayed in the completion too
  end.totals = {.study_cells = 3, .study_references = 1};
  end.success = true;
  end.now_ms = kNow;
  TG_ASSERT_OK_AND_ASSIGN(EndOutcome outcome, store_->EndAttempt(end));
  EXPECT_EQ(outcome, EndOutcome::kApplied);
  // A repeated completion is a no-op too.
  TG_ASSERT_OK_AND_ASSIGN(outcome, store_->EndAttempt(end));
  EXPECT_EQ(outcome, EndOutcome::kAlreadyEnded);

  Reopen();  // durable
  std::vector<StudyCellRecord> cells;
  std::vector<StudyReferenceRecord> refs;
  TG_ASSERT_OK(store_->ListStudyRows("st", false, &cells, &refs));
  ASSERT_EQ(cells.size(), 3u);
  ASSERT_EQ(refs.size(), 1u);
  for (size_t i = 0; i < cells.size(); ++i) {
    EXPECT_EQ(cells[i].job_id, job);
    EXPECT_EQ(cells[i].attempt, 1);
    EXPECT_EQ(cells[i].study, "tiny");
    EXPECT_TRUE(cells[i].final_attempt);
    ExpectSameCell(cells[i].cell, rows.cells[i]);
  }
  const StudyReference& r = refs[0].reference;
  EXPECT_EQ(refs[0].study, "tiny");
  EXPECT_EQ(r.horizon, 5);
  EXPECT_EQ(r.norm, 2.5);
  EXPECT_EQ(r.used, rows.references[0].used);
  EXPECT_EQ(r.replicates, rows.references[0].replicates);
  EXPECT_EQ(r.gradient, rows.references[0].gradient);  // bit for bit through JSON
  EXPECT_EQ(r.standard_error, rows.references[0].standard_error);
  EXPECT_EQ(r.agreement_max_z, 1.25);
  EXPECT_TRUE(r.agree);
  // The study job is not a trial result; the sweep counts no episodes for it.
  TG_ASSERT_OK_AND_ASSIGN(std::vector<results::CompletedTrial> results, store_->ListTrialResults("st"));
  EXPECT_TRUE(results.empty());
  TG_ASSERT_OK_AND_ASSIGN(SweepRecord sweep, store_->GetSweep("st"));
  EXPECT_EQ(sweep.episodes_expected, 3);
  EXPECT_EQ(sweep.jobs_completed, 1);
}

TEST_F(StorageTest, StudyCompletionNamesMissingRowsAndRowsOfTheWrongKindAreRefused) {
  const int64_t job = CreateStudySweepAndLease(store_.get(), "st");
  const StudyRows rows = MakeStudyRows();
  StudyRows partial;
  partial.cells = {rows.cells[0], rows.cells[2]};
  TG_ASSERT_OK(store_->StoreResults({job, 1}, "w1", {{}, partial}, kNow, std::nullopt).status());
  AttemptEnd end;
  end.key = {job, 1};
  end.worker_id = "w1";
  end.attempt_state = AttemptState::kCompleted;
  end.job_state = JobState::kCompleted;
  end.totals = {.study_cells = 3, .study_references = 1};
  end.now_ms = kNow;
  absl::StatusOr<EndOutcome> outcome = store_->EndAttempt(end);
  ASSERT_EQ(outcome.status().code(), absl::StatusCode::kFailedPrecondition) << outcome.status();
  EXPECT_NE(outcome.status().message().find("study_cells rows 1 of 0..2"), std::string::npos)
      << outcome.status();
  // Episodes for a study job, a trial-style completion: refused, nothing changes.
  EXPECT_EQ(store_->StoreResults({job, 1}, "w1", {{MakeEpisode(0)}}, kNow, std::nullopt)
                .status().code(),
            absl::StatusCode::kInvalidArgument);
  AttemptEnd trial_style = end;
  trial_style.totals = {.episodes = 1};
  EXPECT_EQ(store_->EndAttempt(trial_style).status().code(), absl::StatusCode::kInvalidArgument);
  TG_ASSERT_OK_AND_ASSIGN(JobRecord record, store_->GetJob(job));
  EXPECT_EQ(record.state, JobState::kRunning);
  // Study rows for a trial job are refused.
  auto jobs = store_->ListJobs({"st", {}, 0, 1000});
  ASSERT_TRUE(jobs.ok());
  const int64_t trial = jobs->front().id;
  EXPECT_EQ(jobs->front().kind, JobKind::kTrial);
  TG_ASSERT_OK(store_->StartAttempt({trial, 1}, MakeWorker("w1"), kNow, kNow + 90'000));
  EXPECT_EQ(store_->StoreResults({trial, 1}, "w1", {{}, rows}, kNow, std::nullopt).status().code(),
            absl::StatusCode::kInvalidArgument);
  // Fencing applies to study rows like to episodes.
  EXPECT_EQ(store_->StoreResults({job, 2}, "w1", {{}, rows}, kNow, std::nullopt).status().code(),
            absl::StatusCode::kAborted);
  EXPECT_EQ(store_->StoreResults({job, 1}, "w2", {{}, rows}, kNow, std::nullopt).status().code(),
            absl::StatusCode::kAborted);
  // Study candidates say what they are (the scheduler gives them to study workers only).
  TG_ASSERT_OK_AND_ASSIGN(JobRecord again, store_->GetJob(job));
  EXPECT_EQ(again.kind, JobKind::kStudy);
}

// A database written by a build before study jobs (schema version 1) is
// migrated on open: its sweeps are kept and study jobs can be added.
// Schema 4 (issue 15): the file answers questions without the coordinator. The
// view "episodes/<sweep>" has one typed column per swept key, numbers as
// numbers (seeds as integers), and each episode's CPU seconds.
// A sweep of `methods` x `seeds` trial jobs, variant "noise_k=K", whose
// options are a protocol of `protocol_keys` shared options plus the job's
// method, seed and noise_k, in the order a sweep expands them.
NewSweep SweepWithAProtocol(const std::string& name, const std::vector<std::string>& methods,
                            int seeds, int protocol_keys) {
  NewSweep sweep = MakeSweep(name, 0, 3);
  for (int seed = 1; seed <= seeds; ++seed) {
    for (const std::string& method : methods) {
      NewJob job;
      job.method = method;
      job.seed = absl::StrCat(seed);
      job.variant = seed % 2 ? "noise_k=1" : "noise_k=0.01";
      job.options = {{"method", method}, {"seed", job.seed}};
      for (int k = 0; k < protocol_keys; ++k) {
        job.options.emplace_back(absl::StrCat("option_", k), absl::StrCat("value \"", k, "\""));
      }
      job.options.emplace_back("noise_k", seed % 2 ? "1" : "0.01");
      job.episodes_expected = 3;
      sweep.jobs.push_back(job);
    }
  }
  return sweep;
}

// Schema 10: a trial job's options are its sweep's shared list with its own
// swept values; the store keeps the list once per sweep and every read of a
// job, the view job_option_lists and a grown sweep give each job's whole list.
TEST_F(StorageTest, TrialJobsStoreTheirSweepsSharedOptionsOnceAndReadThemWhole) {
  NewSweep sweep = SweepWithAProtocol("shared", {"RP", "TP", "GTP+sn"}, 4, 40);
  // A job whose options differ outside its swept keys is stored whole.
  sweep.jobs[5].options[7].second = "not the protocol's";
  bool created = false;
  TG_ASSERT_OK(store_->CreateSweep(sweep, kNow, &created).status());
  TG_ASSERT_OK_AND_ASSIGN(std::vector<JobRecord> jobs, store_->ListJobs({"shared", {}, 0, 100}));
  ASSERT_EQ(jobs.size(), sweep.jobs.size());
  for (size_t i = 0; i < jobs.size(); ++i) {
    EXPECT_EQ(jobs[i].options, sweep.jobs[i].options) << "job " << i;
    TG_ASSERT_OK_AND_ASSIGN(JobRecord one, store_->GetJob(jobs[i].id));
    EXPECT_EQ(one.options, sweep.jobs[i].options) << "job " << i;
  }
  auto db = internal::Db::OpenReadOnly(path_, 1000);
  ASSERT_TRUE(db.ok()) << db.status();
  TG_ASSERT_OK_AND_ASSIGN(internal::Statement stored, internal::Statement::Prepare(*db, R"sql(
SELECT j.ordinal, j.options_json, l.options_json FROM jobs j
JOIN job_option_lists l ON l.job_id = j.id ORDER BY j.ordinal)sql"));
  for (size_t i = 0; i < jobs.size(); ++i) {
    TG_ASSERT_OK_AND_ASSIGN(bool row, stored.Step());
    ASSERT_TRUE(row);
    EXPECT_EQ(stored.ColumnText(1).empty(), i != 5) << "job " << i << ": " << stored.ColumnText(1);
    EXPECT_EQ(internal::OptionsFromJson(stored.ColumnText(2)), sweep.jobs[i].options) << "job " << i;
  }
  // Growing the sweep compares each existing job's whole list: the same
  // spec grown by a seed adds its jobs, compactly again.
  NewSweep bigger = SweepWithAProtocol("shared", {"RP", "TP", "GTP+sn"}, 5, 40);
  bigger.jobs[5].options[7].second = "not the protocol's";
  bigger.spec_hash = "hash-2";
  TG_ASSERT_OK_AND_ASSIGN(int added, store_->GrowSweep(bigger, kNow));
  EXPECT_EQ(added, 3);
  TG_ASSERT_OK_AND_ASSIGN(jobs, store_->ListJobs({"shared", {}, 0, 100}));
  ASSERT_EQ(jobs.size(), bigger.jobs.size());
  for (size_t i = 0; i < jobs.size(); ++i) EXPECT_EQ(jobs[i].options, bigger.jobs[i].options);
  // A grown job whose protocol differs from the stored one is refused.
  NewSweep changed = SweepWithAProtocol("shared", {"RP", "TP", "GTP+sn"}, 5, 40);
  changed.jobs[0].options[9].second = "another value";
  changed.spec_hash = "hash-3";
  EXPECT_EQ(store_->GrowSweep(changed, kNow).status().code(),
            absl::StatusCode::kFailedPrecondition);
}

// SQLite reads a column by walking the row: a sweep's budgets, which every
// heartbeat and completion reads, come before the texts that grow with its
// spec, or each read walks the spec's overflow pages (schema 10; at 100,000
// queued jobs of one explicit seed list that was half of a heartbeat).
TEST_F(StorageTest, ASweepsBudgetsComeBeforeItsSpecTexts) {
  auto db = internal::Db::OpenReadOnly(path_, 1000);
  ASSERT_TRUE(db.ok()) << db.status();
  TG_ASSERT_OK_AND_ASSIGN(internal::Statement columns, internal::Statement::Prepare(
      *db, "SELECT name, cid FROM pragma_table_info('sweeps')"));
  std::map<std::string, int64_t> position;
  for (;;) {
    TG_ASSERT_OK_AND_ASSIGN(bool row, columns.Step());
    if (!row) break;
    position[columns.ColumnText(0)] = columns.ColumnInt(1);
  }
  for (const char* text : {"canonical_spec", "source_text", "description", "trial_options_json"}) {
    ASSERT_EQ(position.count(text), 1u) << text;
    for (const char* small : {"state", "max_attempts", "max_lost_leases", "max_concurrent"}) {
      ASSERT_EQ(position.count(small), 1u) << small;
      EXPECT_LT(position[small], position[text]) << small << " after " << text;
    }
  }
  // The shared options, read with every job, before the spec's two texts.
  EXPECT_LT(position["trial_options_json"], position["canonical_spec"]);
  EXPECT_LT(position["trial_options_json"], position["source_text"]);
}

// What the shared list saves: 2,000 jobs with a protocol of 55 options took
// about 2.1 KB each in the file (schema 9: every job held the whole list).
TEST_F(StorageTest, AJobsRowDoesNotHoldItsSweepsProtocol) {
  NewSweep sweep = SweepWithAProtocol("bytes", {"PILCO", "RP", "TP", "GTP"}, 500, 55);
  for (NewJob& job : sweep.jobs) {
    for (auto& [key, value] : job.options) {
      if (key.rfind("option_", 0) == 0) value = "1e-08";  // ~ a real option's length
    }
  }
  bool created = false;
  TG_ASSERT_OK(store_->CreateSweep(sweep, kNow, &created).status());
  auto db = internal::Db::OpenReadOnly(path_, 1000);
  ASSERT_TRUE(db.ok()) << db.status();
  TG_ASSERT_OK_AND_ASSIGN(internal::Statement bytes, internal::Statement::Prepare(*db, R"sql(
SELECT SUM(LENGTH(options_json)), COUNT(*) FROM jobs)sql"));
  TG_ASSERT_OK_AND_ASSIGN(bool row, bytes.Step());
  ASSERT_TRUE(row);
  EXPECT_EQ(bytes.ColumnInt(1), 2000);
  EXPECT_EQ(bytes.ColumnInt(0), 0);  // schema 9: about 1.4 KB a job
  TG_ASSERT_OK_AND_ASSIGN(internal::Statement pages, internal::Statement::Prepare(
      *db, "SELECT page_count * page_size FROM pragma_page_count(), pragma_page_size()"));
  TG_ASSERT_OK_AND_ASSIGN(row, pages.Step());
  ASSERT_TRUE(row);
  // The whole file, WAL checkpointed or not: the jobs, their job_options and indexes.
  const int64_t file_bytes = pages.ColumnInt(0);
  EXPECT_LT(file_bytes / 2000, 400) << file_bytes << " bytes for 2,000 jobs";
}

TEST_F(StorageTest, SweepViewHasOneTypedColumnPerSweptKey) {
  NewSweep sweep = MakeSweep("typed", 2, 3);
  sweep.jobs[0].variant = "cost=tip noise_k=0.01";
  sweep.jobs[1].variant = "cost=angle noise_k=1";
  sweep.jobs[1].method = "TP";
  // Schema 9: the protocol's options are (constant) columns too.
  for (storage::NewJob& job : sweep.jobs) {
    job.options.emplace_back("particles", "300");
    job.options.emplace_back("scene", "cart'pole");
    job.options.emplace_back("epsilon", "1e-08");
  }
  bool created = false;
  TG_ASSERT_OK(store_->CreateSweep(sweep, kNow, &created).status());
  TG_ASSERT_OK_AND_ASSIGN(std::vector<JobRecord> jobs, store_->ListJobs({"typed", {}, 0, 10}));
  TG_ASSERT_OK(store_->StartAttempt({jobs[0].id, 1}, MakeWorker("w1"), kNow, kNow + 90'000));
  Episode episode = MakeEpisode(0);
  episode.cpu_seconds = 1.5;
  TG_ASSERT_OK(store_->StoreResults({jobs[0].id, 1}, "w1", {{episode}}, kNow, std::nullopt).status());
  auto db = internal::Db::OpenReadOnly(path_, 1000);
  ASSERT_TRUE(db.ok()) << db.status();
  TG_ASSERT_OK_AND_ASSIGN(internal::Statement query, internal::Statement::Prepare(*db, R"sql(
SELECT method, seed, typeof(seed), cost, typeof(cost), noise_k, typeof(noise_k), cpu_seconds,
       final_attempt, worker_build, particles, typeof(particles), scene, epsilon, typeof(epsilon),
       optimisation_seconds, variant FROM "episodes/typed")sql"));
  TG_ASSERT_OK_AND_ASSIGN(bool row, query.Step());
  ASSERT_TRUE(row);
  EXPECT_EQ(query.ColumnText(0), "RP");
  EXPECT_EQ(query.ColumnInt(1), 1);
  EXPECT_EQ(query.ColumnText(2), "integer");
  EXPECT_EQ(query.ColumnText(3), "tip");
  EXPECT_EQ(query.ColumnText(4), "text");
  EXPECT_EQ(query.ColumnDouble(5), 0.01);
  EXPECT_EQ(query.ColumnText(6), "real");
  EXPECT_EQ(query.ColumnDouble(7), 1.5);
  EXPECT_EQ(query.ColumnInt(8), 0);  // the attempt runs: not the one that completed the job
  EXPECT_EQ(query.ColumnText(9), MakeWorker("w1").build);
  EXPECT_EQ(query.ColumnInt(10), 300);
  EXPECT_EQ(query.ColumnText(11), "integer");
  EXPECT_EQ(query.ColumnText(12), "cart'pole");  // quoted as a literal
  EXPECT_EQ(query.ColumnDouble(13), 1e-08);
  EXPECT_EQ(query.ColumnText(14), "real");
  EXPECT_EQ(query.ColumnDouble(15), MakeEpisode(0).optimisation_seconds);
  EXPECT_EQ(query.ColumnText(16), "cost=tip noise_k=0.01");
  TG_ASSERT_OK_AND_ASSIGN(bool more, query.Step());
  EXPECT_FALSE(more);
  TG_ASSERT_OK_AND_ASSIGN(internal::Statement meta, internal::Statement::Prepare(
      *db, "SELECT value FROM meta WHERE key = 'schema_version'"));
  TG_ASSERT_OK_AND_ASSIGN(bool meta_row, meta.Step());
  ASSERT_TRUE(meta_row);
  EXPECT_EQ(meta.ColumnText(0), std::to_string(internal::kSchemaVersion));
}

TEST_F(StorageTest, VersionOneDatabaseIsMigrated) {
  const int64_t trial_job = CreateAndLease("old");
  std::optional<internal::Db> db_slot;
  ASSERT_NO_FATAL_FAILURE(StoreAnEpisodeAndOpenTheFileRaw(trial_job, &db_slot));
  {
    // Turn the file back into a version-1 database.
    internal::Db* db = &*db_slot;
    TG_ASSERT_OK(::totalgrad::testing::DropColumnsAddedAfter(*db, 1));
    TG_ASSERT_OK(db->Exec("DROP TABLE job_options; ALTER TABLE episodes DROP COLUMN cpu_seconds; "
                          "DELETE FROM meta; "
                          "DROP TABLE checkpoints; DROP TABLE study_cells; DROP TABLE study_references; "
                          "ALTER TABLE jobs DROP COLUMN payload; ALTER TABLE jobs DROP COLUMN kind; "
                          "PRAGMA user_version=1"));
  }
  db_slot.reset();  // closed before the store opens the file again
  Reopen();
  {
    auto db = internal::Db::Open(path_, false, 1000);
    ASSERT_TRUE(db.ok());
    TG_ASSERT_OK_AND_ASSIGN(internal::Statement version,
                            internal::Statement::Prepare(*db, "PRAGMA user_version"));
    TG_ASSERT_OK_AND_ASSIGN(bool row, version.Step());
    ASSERT_TRUE(row);
    EXPECT_EQ(version.ColumnInt(0), internal::kSchemaVersion);
  }
  // The old file was copied before it was changed.
  EXPECT_TRUE(std::filesystem::exists(path_ + ".schema-v1-backup"));
  TG_ASSERT_OK_AND_ASSIGN(JobRecord old, store_->GetJob(trial_job));
  EXPECT_EQ(old.kind, JobKind::kTrial);
  EXPECT_EQ(old.episodes_stored, 1);
  const int64_t job = CreateStudySweepAndLease(store_.get(), "new");
  TG_ASSERT_OK_AND_ASSIGN(ResultTotals stored, store_->StoreResults(
                                                    {job, 1}, "w1", {{}, MakeStudyRows()}, kNow,
                                                    std::nullopt));
  EXPECT_EQ(stored.study_cells + stored.study_references, 4);
  // A newer schema than this build knows is refused.
  store_.reset();
  {
    auto db = internal::Db::Open(path_, false, 1000);
    ASSERT_TRUE(db.ok());
    TG_ASSERT_OK(db->Exec("PRAGMA user_version=99"));
  }
  auto newer = SqliteStore::Open(path_);
  EXPECT_EQ(newer.status().code(), absl::StatusCode::kFailedPrecondition) << newer.status();
  {
    auto db = internal::Db::Open(path_, false, 1000);
    ASSERT_TRUE(db.ok());
    TG_ASSERT_OK(db->Exec(absl::StrCat("PRAGMA user_version=", internal::kSchemaVersion)));
  }
  Reopen();
}

// Version 4 stored seeds as TEXT; version 5 rebuilds jobs with an INTEGER
// seed, keeping every row, the other tables' references and the views.
TEST_F(StorageTest, VersionFourDatabaseGetsIntegerSeeds) {
  const int64_t job = CreateAndLease("texts");
  std::optional<internal::Db> db_slot;
  ASSERT_NO_FATAL_FAILURE(StoreAnEpisodeAndOpenTheFileRaw(job, &db_slot));
  {
    // Back to version 4: jobs rebuilt with seed TEXT, as version 4 had it,
    // and study_references without version 6's column.
    internal::Db* db = &*db_slot;
    TG_ASSERT_OK(::totalgrad::testing::DropColumnsAddedAfter(*db, 4));
    TG_ASSERT_OK(db->Exec(
        "ALTER TABLE study_references DROP COLUMN agreement_resolution; "
        "PRAGMA foreign_keys=OFF; "
        "CREATE TABLE jobs_text AS SELECT id, sweep_id, ordinal, method, CAST(seed AS TEXT) AS "
        "seed, variant, options_json, episodes_expected, state, attempts, failures, lost_leases, "
        "completed_attempt, success, final_eval_cost, last_error, kind, payload FROM jobs; "
        "DROP TABLE jobs; ALTER TABLE jobs_text RENAME TO jobs; PRAGMA user_version=4"));
    TG_ASSERT_OK_AND_ASSIGN(internal::Statement type, internal::Statement::Prepare(
        *db, "SELECT typeof(seed) FROM jobs"));
    TG_ASSERT_OK_AND_ASSIGN(bool row, type.Step());
    ASSERT_TRUE(row);
    ASSERT_EQ(type.ColumnText(0), "text");  // the test's premise
  }
  db_slot.reset();  // closed before the store opens the file again
  Reopen();
  EXPECT_TRUE(std::filesystem::exists(path_ + ".schema-v4-backup"));
  auto db = internal::Db::OpenReadOnly(path_, 1000);
  ASSERT_TRUE(db.ok()) << db.status();
  TG_ASSERT_OK_AND_ASSIGN(internal::Statement query, internal::Statement::Prepare(*db, R"sql(
SELECT typeof(j.seed), j.seed, (SELECT COUNT(*) FROM "episodes/texts"),
       (SELECT typeof(seed) FROM episode_rows LIMIT 1) FROM jobs j)sql"));
  TG_ASSERT_OK_AND_ASSIGN(bool row, query.Step());
  ASSERT_TRUE(row);
  EXPECT_EQ(query.ColumnText(0), "integer");
  TG_ASSERT_OK_AND_ASSIGN(JobRecord migrated, store_->GetJob(job));
  EXPECT_EQ(query.ColumnText(1), migrated.seed);
  EXPECT_EQ(query.ColumnInt(2), 1);
  EXPECT_EQ(query.ColumnText(3), "integer");
  EXPECT_EQ(migrated.episodes_stored, 1);
  // Later writes still find the job by its seed (bound as text).
  TG_ASSERT_OK(store_->StoreResults({job, 1}, "w1", {{MakeEpisode(1)}}, kNow, std::nullopt)
                   .status());
  TG_ASSERT_OK_AND_ASSIGN(migrated, store_->GetJob(job));
  EXPECT_EQ(migrated.episodes_stored, 2);
}

// Issue 15: a sweep is deleted with every row stored for it, in one
// transaction, only when it holds what the caller archived and no worker
// runs one of its trials; other sweeps are untouched.
TEST_F(StorageTest, DeleteSweepRemovesEveryRowOnlyWhenIdleAndAsArchived) {
  const int64_t kept_job = CreateAndLease("kept");
  TG_ASSERT_OK(store_->StoreResults({kept_job, 1}, "w1", {{MakeEpisode(0)}}, kNow, std::nullopt)
                   .status());
  const int64_t job = CreateAndLease("gone", /*jobs=*/2);
  TG_ASSERT_OK(store_->StoreResults({job, 1}, "w1", {{MakeEpisode(0), MakeEpisode(1)}}, kNow,
                                     std::nullopt).status());
  const SweepContents archived{.jobs = 2, .attempts = 1, .episodes = 2, .study_rows = 0};
  // A worker holds a lease: refused, nothing deleted.
  auto running = store_->DeleteSweep("gone", archived, kNow);
  EXPECT_EQ(running.status().code(), absl::StatusCode::kFailedPrecondition) << running.status();
  EXPECT_NE(running.status().message().find("totalgrad sweep cancel gone"), std::string::npos)
      << running.status();
  TG_ASSERT_OK(LoseLease({job, 1}));
  // Counts other than the sweep's (an archive written before a change): refused.
  SweepContents stale = archived;
  stale.episodes = 1;
  auto changed = store_->DeleteSweep("gone", stale, kNow);
  EXPECT_EQ(changed.status().code(), absl::StatusCode::kFailedPrecondition) << changed.status();
  EXPECT_NE(changed.status().message().find("changed after it was archived"), std::string::npos)
      << changed.status();
  TG_ASSERT_OK(store_->GetSweep("gone").status());
  TG_ASSERT_OK_AND_ASSIGN(SweepContents deleted, store_->DeleteSweep("gone", archived, kNow));
  EXPECT_EQ(deleted, archived);
  EXPECT_EQ(store_->GetSweep("gone").status().code(), absl::StatusCode::kNotFound);
  EXPECT_EQ(store_->DeleteSweep("gone", archived, kNow).status().code(),
            absl::StatusCode::kNotFound);
  // No row of it is left anywhere, the other sweep keeps all of its rows.
  auto db = internal::Db::OpenReadOnly(path_, 1000);
  ASSERT_TRUE(db.ok()) << db.status();
  for (const std::string table : {"jobs", "attempts", "episodes", "job_options", "events"}) {
    TG_ASSERT_OK_AND_ASSIGN(internal::Statement count, internal::Statement::Prepare(
        *db, absl::StrCat("SELECT COUNT(*) FROM ", table, " WHERE ",
                          table == "jobs" ? "id" : "job_id", " = ", job)));
    TG_ASSERT_OK_AND_ASSIGN(bool row, count.Step());
    ASSERT_TRUE(row);
    EXPECT_EQ(count.ColumnInt(0), 0) << table;
  }
  TG_ASSERT_OK_AND_ASSIGN(internal::Statement views, internal::Statement::Prepare(
      *db, "SELECT group_concat(name) FROM sqlite_schema WHERE type = 'view' AND name LIKE 'episodes/%'"));
  TG_ASSERT_OK_AND_ASSIGN(bool row, views.Step());
  ASSERT_TRUE(row);
  EXPECT_EQ(views.ColumnText(0), "episodes/kept");
  TG_ASSERT_OK_AND_ASSIGN(internal::Statement event, internal::Statement::Prepare(
      *db, "SELECT message FROM events WHERE kind = 'sweep_deleted'"));
  TG_ASSERT_OK_AND_ASSIGN(row, event.Step());
  ASSERT_TRUE(row);
  EXPECT_EQ(event.ColumnText(0), "sweep 'gone': 2 jobs, 1 attempts, 2 episodes, 0 study rows");
  TG_ASSERT_OK_AND_ASSIGN(JobRecord kept, store_->GetJob(kept_job));
  EXPECT_EQ(kept.episodes_stored, 1);
  TG_ASSERT_OK_AND_ASSIGN(internal::Statement keys,
                          internal::Statement::Prepare(*db, "PRAGMA foreign_key_check"));
  TG_ASSERT_OK_AND_ASSIGN(row, keys.Step());
  EXPECT_FALSE(row);
}

}  // namespace storage_test
}  // namespace totalgrad::storage
