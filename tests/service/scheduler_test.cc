// The scheduler on a real SQLite store with a fake clock: exactly-once claims,
// lease expiry and fencing, duplicate delivery, attempt budgets, pause,
// cancel, drain, restart recovery, store faults.
#include "server/scheduler/scheduler.h"

#include <gtest/gtest.h>

#include <atomic>
#include <chrono>
#include <filesystem>
#include <limits>
#include <set>
#include <thread>

#include "absl/strings/str_cat.h"
#include "server/storage/sqlite_store.h"
#include "tests/service/service_testutil.h"

namespace totalgrad::scheduler {
namespace scheduler_test {

using storage::AttemptState;
using storage::Episode;
using storage::JobRecord;
using storage::JobState;
using storage::LeaseKey;
using storage::SweepState;
using ::totalgrad::testing::FaultyStore;
using ::totalgrad::testing::MakeEpisode;
using ::totalgrad::testing::MakeSweep;
using ::totalgrad::testing::MakeTempDir;
using ::totalgrad::testing::MakeWorker;

class SchedulerTest : public ::testing::Test {
 protected:
  void SetUp() override {
    path_ = MakeTempDir() + "/scheduler.db";
    auto store = storage::SqliteStore::Open(path_);
    ASSERT_TRUE(store.ok()) << store.status();
    store_ = std::move(*store);
    faulty_ = std::make_unique<FaultyStore>(store_.get());
    options_.heartbeat_interval = absl::Seconds(15);
    options_.lease_timeout = absl::Seconds(90);
    scheduler_ = std::make_unique<Scheduler>(faulty_.get(), &clock_, options_);
  }
  void TearDown() override {
    scheduler_.reset();
    faulty_.reset();
    store_.reset();
    if (!HasFailure()) std::filesystem::remove_all(std::filesystem::path(path_).parent_path());
  }
  void Submit(const std::string& name, int jobs, int episodes, int max_attempts = 3,
              int max_lost = 20, int max_concurrent = 0) {
    storage::NewSweep sweep = MakeSweep(name, jobs, episodes);
    sweep.max_attempts = max_attempts;
    sweep.max_lost_leases = max_lost;
    sweep.max_concurrent = max_concurrent;
    bool created = false;
    auto result = scheduler_->SubmitSweep(sweep, &created);
    ASSERT_TRUE(result.ok()) << result.status();
  }
  Lease MustAcquire(const std::string& worker) {
    auto lease = scheduler_->TryAcquire(MakeWorker(worker));
    EXPECT_TRUE(lease.ok()) << lease.status();
    EXPECT_TRUE(lease.ok() && lease->has_value()) << "no lease for " << worker;
    return lease.ok() && lease->has_value() ? **lease : Lease{};
  }
  bool NothingToAcquire(const std::string& worker) {
    auto lease = scheduler_->TryAcquire(MakeWorker(worker));
    EXPECT_TRUE(lease.ok()) << lease.status();
    return lease.ok() && !lease->has_value();
  }
  JobRecord Job(int64_t id) {
    auto job = store_->GetJob(id);
    EXPECT_TRUE(job.ok()) << job.status();
    return job.ok() ? *job : JobRecord{};
  }
  // Lets `ms` of time pass while the coordinator's lease loop runs every
  // `step_ms` (as Coordinator::ExpiryLoop does); returns the leases lost.
  int RunLeaseLoopFor(int64_t ms, int64_t step_ms = 1000) {
    int expired = 0;
    for (int64_t passed = 0; passed < ms; passed += step_ms) {
      clock_.AdvanceMs(std::min(step_ms, ms - passed));
      auto count = scheduler_->ExpireLeases();
      EXPECT_TRUE(count.ok()) << count.status();
      if (count.ok()) expired += *count;
    }
    return expired;
  }
  std::vector<Episode> Episodes(int from, int to) {
    std::vector<Episode> episodes;
    for (int e = from; e < to; ++e) episodes.push_back(MakeEpisode(e, 10 + e));
    return episodes;
  }
  // A trial's completion: its unacknowledged episodes, its total and verdict.
  static storage::JobCompletion TrialCompletion(std::vector<Episode> episodes, int total,
                                                bool success, double final_eval_cost) {
    storage::JobCompletion completion;
    completion.results.episodes = std::move(episodes);
    completion.totals.episodes = total;
    completion.success = success;
    completion.final_eval_cost = final_eval_cost;
    return completion;
  }

  std::string path_;
  FakeClock clock_;
  SchedulerOptions options_;
  std::unique_ptr<storage::SqliteStore> store_;
  std::unique_ptr<FaultyStore> faulty_;
  std::unique_ptr<Scheduler> scheduler_;
};

TEST(SchedulerOptionsTest, ValidateNamesTheBadField) {
  SchedulerOptions options;
  TG_EXPECT_OK(options.Validate());
  options.lease_timeout = absl::Seconds(10);
  const absl::Status status = options.Validate();
  EXPECT_EQ(status.code(), absl::StatusCode::kInvalidArgument);
  EXPECT_NE(status.message().find("lease_timeout"), std::string::npos) << status;
}

// T1: many workers racing for few jobs get each job exactly once.
TEST_F(SchedulerTest, ConcurrentWorkersClaimEachJobExactlyOnce) {
  constexpr int kJobs = 12;
  constexpr int kWorkers = 8;
  Submit("s", kJobs, 2);
  std::mutex mutex;
  std::vector<int64_t> granted;
  std::vector<std::thread> threads;
  for (int w = 0; w < kWorkers; ++w) {
    threads.emplace_back([&, w] {
      while (true) {
        auto lease = scheduler_->TryAcquire(MakeWorker(absl::StrCat("w", w)));
        ASSERT_TRUE(lease.ok()) << lease.status();
        if (!lease->has_value()) return;
        std::lock_guard<std::mutex> lock(mutex);
        granted.push_back((*lease)->key.job_id);
      }
    });
  }
  for (auto& t : threads) t.join();
  EXPECT_EQ(granted.size(), static_cast<size_t>(kJobs));
  EXPECT_EQ(std::set<int64_t>(granted.begin(), granted.end()).size(), static_cast<size_t>(kJobs));
}

TEST_F(SchedulerTest, LeaseCarriesTheJobAndTimings) {
  Submit("s", 1, 3);
  const Lease lease = MustAcquire("w1");
  EXPECT_EQ(lease.key.attempt, 1);
  EXPECT_EQ(lease.job.method, "RP");
  EXPECT_EQ(lease.job.seed, "1");
  EXPECT_EQ(lease.job.episodes_expected, 3);
  EXPECT_EQ(lease.job.options.size(), 3u);
  EXPECT_EQ(lease.heartbeat_interval_ms, 15'000);
  EXPECT_EQ(lease.lease_timeout_ms, 90'000);
  EXPECT_TRUE(NothingToAcquire("w2"));
}

// T2: a lease without heartbeats is lost on the coordinator's clock, the job
// goes back to the queue, and the old worker's late writes are refused.
TEST_F(SchedulerTest, SilentLeaseExpiresAndLateWritesAreRefused) {
  Submit("s", 1, 3);
  const Lease first = MustAcquire("w1");
  TG_ASSERT_OK(scheduler_->Heartbeat("w1", first.key, {Episodes(0, 1)}));
  clock_.AdvanceMs(89'000);
  TG_ASSERT_OK_AND_ASSIGN(int expired, scheduler_->ExpireLeases());
  EXPECT_EQ(expired, 0);
  clock_.AdvanceMs(2'000);
  TG_ASSERT_OK_AND_ASSIGN(expired, scheduler_->ExpireLeases());
  EXPECT_EQ(expired, 1);
  JobRecord job = Job(first.key.job_id);
  EXPECT_EQ(job.state, JobState::kQueued);
  EXPECT_EQ(job.lost_leases, 1);
  EXPECT_EQ(job.failures, 0);

  const Lease second = MustAcquire("w2");
  EXPECT_EQ(second.key.job_id, first.key.job_id);
  EXPECT_EQ(second.key.attempt, 2);

  auto late_beat = scheduler_->Heartbeat("w1", first.key, {Episodes(1, 2)});
  EXPECT_EQ(late_beat.status().code(), absl::StatusCode::kAborted) << late_beat.status();
  auto late_complete = scheduler_->Complete("w1", first.key, TrialCompletion(Episodes(1, 3), 3, true, 1.0));
  EXPECT_EQ(late_complete.code(), absl::StatusCode::kAborted) << late_complete;
  auto late_fail = scheduler_->Fail("w1", first.key, {}, "boom");
  EXPECT_EQ(late_fail.status().code(), absl::StatusCode::kAborted);

  job = Job(first.key.job_id);
  EXPECT_EQ(job.state, JobState::kRunning);
  EXPECT_EQ(job.worker_id, "w2");
  EXPECT_EQ(job.episodes_stored, 0);
  TG_ASSERT_OK_AND_ASSIGN(auto attempts, store_->ListAttempts(first.key.job_id));
  ASSERT_EQ(attempts.size(), 2u);
  EXPECT_EQ(attempts[0].state, AttemptState::kLeaseLost);
  EXPECT_EQ(attempts[0].episodes_stored, 1);
}

TEST_F(SchedulerTest, HeartbeatsKeepALeaseAlive) {
  Submit("s", 1, 3);
  const Lease lease = MustAcquire("w1");
  for (int i = 0; i < 5; ++i) {
    EXPECT_EQ(RunLeaseLoopFor(80'000), 0);
    TG_ASSERT_OK_AND_ASSIGN(HeartbeatResult beat, scheduler_->Heartbeat("w1", lease.key, {}));
    EXPECT_EQ(beat.directive, Directive::kContinue);
  }
  EXPECT_EQ(RunLeaseLoopFor(91'000), 1);  // and without them it is lost
}

// T3: every worker call delivered twice leaves the same state as once.
TEST_F(SchedulerTest, DuplicateDeliveryIsANoOp) {
  Submit("s", 2, 3);
  const Lease a = MustAcquire("w1");
  const Lease b = MustAcquire("w2");
  for (int repeat = 0; repeat < 2; ++repeat) {
    TG_ASSERT_OK_AND_ASSIGN(HeartbeatResult beat, scheduler_->Heartbeat("w1", a.key, {Episodes(0, 2)}));
    EXPECT_EQ(beat.stored.episodes, 2);
  }
  for (int repeat = 0; repeat < 2; ++repeat) {
    TG_ASSERT_OK(scheduler_->Complete("w1", a.key, TrialCompletion(Episodes(2, 3), 3, true, 4.5)));
  }
  for (int repeat = 0; repeat < 2; ++repeat) {
    TG_ASSERT_OK_AND_ASSIGN(bool requeued, scheduler_->Fail("w2", b.key, Episodes(0, 1), "diverged"));
    EXPECT_TRUE(requeued);
  }
  // A beat overtaken by its own completion is refused and changes nothing.
  EXPECT_EQ(scheduler_->Heartbeat("w1", a.key, {Episodes(0, 3)}).status().code(),
            absl::StatusCode::kAborted);
  const JobRecord done = Job(a.key.job_id);
  EXPECT_EQ(done.state, JobState::kCompleted);
  EXPECT_EQ(done.episodes_stored, 3);
  EXPECT_EQ(done.final_eval_cost, 4.5);
  const JobRecord failed_once = Job(b.key.job_id);
  EXPECT_EQ(failed_once.state, JobState::kQueued);
  EXPECT_EQ(failed_once.failures, 1);  // not 2
  TG_ASSERT_OK_AND_ASSIGN(auto sweep, store_->GetSweep("s"));
  EXPECT_EQ(sweep.jobs_completed, 1);
}

// T7: application failures use max_attempts; lost leases and releases do not.
TEST_F(SchedulerTest, FailuresCountAgainstMaxAttemptsButLostLeasesDoNot) {
  Submit("s", 1, 2, /*max_attempts=*/2, /*max_lost=*/20);
  Lease lease = MustAcquire("w1");
  for (int i = 0; i < 3; ++i) {  // three lost leases
    EXPECT_EQ(RunLeaseLoopFor(91'000), 1);
    lease = MustAcquire("w1");
  }
  TG_ASSERT_OK(scheduler_->Release("w1", lease.key, "drain"));  // and a release
  lease = MustAcquire("w1");
  TG_ASSERT_OK_AND_ASSIGN(bool requeued, scheduler_->Fail("w1", lease.key, {}, "first"));
  EXPECT_TRUE(requeued);
  lease = MustAcquire("w1");
  TG_ASSERT_OK_AND_ASSIGN(requeued, scheduler_->Fail("w1", lease.key, {}, "second"));
  EXPECT_FALSE(requeued);
  const JobRecord job = Job(lease.key.job_id);
  EXPECT_EQ(job.state, JobState::kFailed);
  EXPECT_EQ(job.failures, 2);
  EXPECT_EQ(job.lost_leases, 4);
  EXPECT_EQ(job.attempts, 6);
  EXPECT_EQ(job.last_error, "second");
  EXPECT_TRUE(NothingToAcquire("w1"));
}

TEST_F(SchedulerTest, APoisonLeaseLoserStopsAtMaxLostLeases) {
  Submit("s", 1, 2, /*max_attempts=*/3, /*max_lost=*/2);
  MustAcquire("w1");
  EXPECT_EQ(RunLeaseLoopFor(91'000), 1);
  const Lease second = MustAcquire("w1");
  EXPECT_EQ(RunLeaseLoopFor(91'000), 1);
  const JobRecord job = Job(second.key.job_id);
  EXPECT_EQ(job.state, JobState::kFailed);
  EXPECT_NE(job.last_error.find("gave up after 2 lost or released leases"), std::string::npos)
      << job.last_error;
}

// A lease whose AcquireLease call was cancelled never reached a worker:
// returning it re-queues the job without charging max_lost_leases, however
// often it happens, while a release by a worker that held the lease does.
TEST_F(SchedulerTest, UndeliveredLeasesDoNotChargeTheLostLeaseBudget) {
  Submit("s", 1, 2, /*max_attempts=*/3, /*max_lost=*/2);
  for (int i = 0; i < 3; ++i) {
    const Lease lease = MustAcquire("w1");
    TG_ASSERT_OK(scheduler_->ReturnUndelivered("w1", lease.key, "poll cancelled"));
    TG_ASSERT_OK(scheduler_->ReturnUndelivered("w1", lease.key, "poll cancelled"));  // no-op
    const JobRecord job = Job(lease.key.job_id);
    EXPECT_EQ(job.state, JobState::kQueued);
    EXPECT_EQ(job.lost_leases, 0);
    EXPECT_EQ(job.failures, 0);
    EXPECT_EQ(job.attempts, i + 1);
    EXPECT_EQ(job.last_error, "undelivered: poll cancelled");
  }
  const Lease held = MustAcquire("w1");
  TG_ASSERT_OK(scheduler_->Release("w1", held.key, "drain"));
  EXPECT_EQ(Job(held.key.job_id).lost_leases, 1);
  // Only the worker that was granted the attempt may return it.
  const Lease again = MustAcquire("w1");
  EXPECT_FALSE(scheduler_->ReturnUndelivered("w2", again.key, "not mine").ok());
  EXPECT_EQ(Job(again.key.job_id).state, JobState::kRunning);
}

// Issue 15: one job of a cancelled sweep can be retried: it runs alone (the
// sweep runs again; its other cancelled jobs stay cancelled).
TEST_F(SchedulerTest, RetryingACancelledSweepsJobRunsItAlone) {
  Submit("s", 2, 2);
  TG_ASSERT_OK(scheduler_->SetSweepState("s", SweepState::kCancelled));
  TG_ASSERT_OK_AND_ASSIGN(auto jobs, store_->ListJobs({"s", {}, 0, 10}));
  ASSERT_EQ(jobs.size(), 2u);
  TG_ASSERT_OK_AND_ASSIGN(JobRecord retried, scheduler_->RetryJob(jobs[1].id));
  EXPECT_EQ(retried.state, JobState::kQueued);
  TG_ASSERT_OK_AND_ASSIGN(auto sweep, store_->GetSweep("s"));
  EXPECT_EQ(sweep.state, SweepState::kRunning);
  EXPECT_EQ(Job(jobs[0].id).state, JobState::kCancelled);
  const Lease lease = MustAcquire("w1");
  EXPECT_EQ(lease.key.job_id, jobs[1].id);
  EXPECT_TRUE(NothingToAcquire("w2"));
}

TEST_F(SchedulerTest, RetryGivesAFailedJobAFreshBudget) {
  Submit("s", 1, 2, /*max_attempts=*/1);
  Lease lease = MustAcquire("w1");
  TG_ASSERT_OK(scheduler_->Fail("w1", lease.key, {}, "bad"));
  EXPECT_EQ(Job(lease.key.job_id).state, JobState::kFailed);
  TG_ASSERT_OK_AND_ASSIGN(JobRecord retried, scheduler_->RetryJob(lease.key.job_id));
  EXPECT_EQ(retried.state, JobState::kQueued);
  lease = MustAcquire("w1");
  EXPECT_EQ(lease.key.attempt, 2);
  EXPECT_EQ(scheduler_->RetryJob(lease.key.job_id).status().code(),
            absl::StatusCode::kFailedPrecondition);
}

TEST_F(SchedulerTest, PausedSweepsHandOutNothingButRunningTrialsContinue) {
  Submit("s", 2, 2);
  const Lease running = MustAcquire("w1");
  TG_ASSERT_OK(scheduler_->SetSweepState("s", SweepState::kPaused));
  EXPECT_TRUE(NothingToAcquire("w2"));
  TG_ASSERT_OK_AND_ASSIGN(HeartbeatResult beat,
                          scheduler_->Heartbeat("w1", running.key, {Episodes(0, 2)}));
  EXPECT_EQ(beat.directive, Directive::kContinue);
  TG_ASSERT_OK(scheduler_->Complete("w1", running.key, TrialCompletion({}, 2, false, 30)));
  TG_ASSERT_OK(scheduler_->SetSweepState("s", SweepState::kRunning));
  MustAcquire("w2");
}

TEST_F(SchedulerTest, CancelTellsRunningTrialsToStopAndOnlyAResumeUndoesIt) {
  Submit("s", 3, 2);
  const Lease running = MustAcquire("w1");
  TG_ASSERT_OK_AND_ASSIGN(auto sweep, scheduler_->SetSweepState("s", SweepState::kCancelled));
  EXPECT_EQ(sweep.jobs_cancelled, 3);
  TG_ASSERT_OK_AND_ASSIGN(HeartbeatResult beat,
                          scheduler_->Heartbeat("w1", running.key, {Episodes(0, 1)}));
  EXPECT_EQ(beat.directive, Directive::kCancel);
  TG_ASSERT_OK(scheduler_->Release("w1", running.key, "cancelled"));
  TG_ASSERT_OK(scheduler_->Release("w1", running.key, "cancelled"));  // repeated: no-op
  TG_ASSERT_OK_AND_ASSIGN(auto attempts, store_->ListAttempts(running.key.job_id));
  EXPECT_EQ(attempts[0].state, AttemptState::kCancelled);
  EXPECT_EQ(Job(running.key.job_id).state, JobState::kCancelled);
  EXPECT_EQ(Job(running.key.job_id).lost_leases, 0);
  EXPECT_TRUE(NothingToAcquire("w2"));
  EXPECT_EQ(scheduler_->SetSweepState("s", SweepState::kPaused).status().code(),
            absl::StatusCode::kFailedPrecondition);
  EXPECT_EQ(scheduler_->SetSweepState("missing", SweepState::kPaused).status().code(),
            absl::StatusCode::kNotFound);
  TG_ASSERT_OK_AND_ASSIGN(sweep, scheduler_->SetSweepState("s", SweepState::kRunning));
  EXPECT_EQ(sweep.jobs_queued, 3);
  EXPECT_EQ(MustAcquire("w2").key.job_id, running.key.job_id);
}

TEST_F(SchedulerTest, DrainingWorkerGetsDrainAndNoNewLeases) {
  Submit("s", 2, 2);
  const Lease lease = MustAcquire("w1");
  TG_ASSERT_OK(scheduler_->DrainWorker("w1"));
  TG_ASSERT_OK_AND_ASSIGN(HeartbeatResult beat, scheduler_->Heartbeat("w1", lease.key, {}));
  EXPECT_EQ(beat.directive, Directive::kDrain);
  EXPECT_TRUE(NothingToAcquire("w1"));
  MustAcquire("w2");
  EXPECT_EQ(scheduler_->DrainWorker("never-seen").status().code(), absl::StatusCode::kNotFound);
}

// A new attempt resumes from the furthest checkpoint its worker's own build
// wrote (a worker resumes no other build's), and from the furthest of any
// build only when its build wrote none (the worker then says why it starts
// over).
TEST_F(SchedulerTest, ANewAttemptResumesFromItsOwnBuildsFurthestCheckpoint) {
  Submit("s", 1, 20);
  const auto of_build = [](const std::string& id, const std::string& build) {
    storage::WorkerIdentity worker = MakeWorker(id);
    worker.build = build;
    return worker;
  };
  const auto lease_for = [&](const storage::WorkerIdentity& worker) {
    auto lease = scheduler_->TryAcquire(worker);
    EXPECT_TRUE(lease.ok() && lease->has_value()) << lease.status();
    return lease.ok() && lease->has_value() ? **lease : Lease{};
  };
  const Lease first = lease_for(of_build("a", "A"));
  TG_ASSERT_OK(store_->StoreCheckpoint(first.key, "a", {9, 1, "A after 9"}, clock_.NowMs()));
  TG_ASSERT_OK(scheduler_->Release("a", first.key, "drain"));
  const Lease second = lease_for(of_build("b", "B"));
  ASSERT_TRUE(second.resume_from.has_value());
  EXPECT_EQ(second.resume_from->checkpoint.data, "A after 9");  // none of B's yet
  TG_ASSERT_OK(store_->StoreCheckpoint(second.key, "b", {3, 1, "B after 3"}, clock_.NowMs()));
  TG_ASSERT_OK(scheduler_->Release("b", second.key, "drain"));
  const Lease third = lease_for(of_build("b", "B"));
  ASSERT_TRUE(third.resume_from.has_value());
  EXPECT_EQ(third.resume_from->checkpoint.data, "B after 3");  // B's own, though A's is further
  EXPECT_EQ(third.resume_from->key.attempt, 2);
  TG_ASSERT_OK(scheduler_->Release("b", third.key, "drain"));
  const Lease fourth = lease_for(of_build("a", "A"));
  ASSERT_TRUE(fourth.resume_from.has_value());
  EXPECT_EQ(fourth.resume_from->checkpoint.data, "A after 9");
}

// A drain stops the process it was asked for; the next process with the
// same id (started after the drained one exited) gets work again, and the
// store records the undrain as an event.
TEST_F(SchedulerTest, ADrainedIdServesItsNextProcess) {
  Submit("s", 3, 2);
  const auto process = [](const std::string& instance, bool takes_over = false) {
    storage::WorkerIdentity worker = MakeWorker("w");
    worker.instance = instance;
    worker.host = "h";
    worker.takes_over = takes_over;
    return worker;
  };
  TG_ASSERT_OK_AND_ASSIGN(std::optional<Lease> first, scheduler_->TryAcquire(process("a")));
  ASSERT_TRUE(first.has_value());
  TG_ASSERT_OK(scheduler_->DrainWorker("w"));
  TG_ASSERT_OK_AND_ASSIGN(std::optional<Lease> drained, scheduler_->TryAcquire(process("a")));
  EXPECT_FALSE(drained.has_value());
  TG_ASSERT_OK_AND_ASSIGN(storage::WorkerRecord record, store_->GetWorker("w"));
  EXPECT_TRUE(record.draining);
  // "a" exited; its successor on the host holds the id's lock.
  TG_ASSERT_OK_AND_ASSIGN(std::optional<Lease> next, scheduler_->TryAcquire(process("b", true)));
  EXPECT_TRUE(next.has_value());
  TG_ASSERT_OK_AND_ASSIGN(record, store_->GetWorker("w"));
  EXPECT_FALSE(record.draining);
  // After a coordinator restart no process is known: a drain asked before
  // any is heard from holds for the next one to ask.
  scheduler_ = std::make_unique<Scheduler>(faulty_.get(), &clock_, options_);
  TG_ASSERT_OK(scheduler_->DrainWorker("w"));
  TG_ASSERT_OK_AND_ASSIGN(drained, scheduler_->TryAcquire(process("c", true)));
  EXPECT_FALSE(drained.has_value());
  TG_ASSERT_OK_AND_ASSIGN(drained, scheduler_->TryAcquire(process("c")));
  EXPECT_FALSE(drained.has_value());
}

// Issue 12.6: two live processes with the same worker id are refused
// (ALREADY_EXISTS) whatever host they run on; a process that holds the
// host-local lock takes the id over from a dead predecessor on its host (and
// the predecessor stays refused); after lease_timeout of silence anyone may
// take the id over.
TEST_F(SchedulerTest, DuplicateWorkerIdsAreRefused) {
  const auto process = [](const std::string& instance, const std::string& host,
                          bool takes_over = false) {
    storage::WorkerIdentity worker = MakeWorker("w");
    worker.instance = instance;
    worker.host = host;
    worker.takes_over = takes_over;
    return worker;
  };
  TG_ASSERT_OK(scheduler_->TryAcquire(process("a", "h1")));
  auto other_host = scheduler_->TryAcquire(process("b", "h2", /*takes_over=*/true));
  EXPECT_EQ(other_host.status().code(), absl::StatusCode::kAlreadyExists);
  EXPECT_NE(other_host.status().message().find("in use by another live worker process on host 'h1'"),
            std::string::npos)
      << other_host.status();
  auto same_host_without_lock = scheduler_->TryAcquire(process("c", "h1"));
  EXPECT_EQ(same_host_without_lock.status().code(), absl::StatusCode::kAlreadyExists);
  // The successor on h1 (it holds the lock, so "a" has exited) takes over...
  TG_ASSERT_OK(scheduler_->TryAcquire(process("d", "h1", /*takes_over=*/true)));
  // ...and the replaced process is refused from then on.
  auto replaced = scheduler_->TryAcquire(process("a", "h1"));
  EXPECT_EQ(replaced.status().code(), absl::StatusCode::kAlreadyExists);
  EXPECT_NE(replaced.status().message().find("replaced by a newer process"), std::string::npos)
      << replaced.status();
  // A process silent for a lease timeout is gone: another host may use the id.
  clock_.AdvanceMs(91'000);
  TG_ASSERT_OK(scheduler_->TryAcquire(process("e", "h2")));
  // Workers that send no instance (older builds) are not checked.
  TG_ASSERT_OK(scheduler_->TryAcquire(process("", "h3")));
}

TEST_F(SchedulerTest, MaxConcurrentLimitsRunningJobsPerSweep) {
  Submit("s", 4, 2, 3, 20, /*max_concurrent=*/2);
  const Lease a = MustAcquire("w1");
  MustAcquire("w2");
  EXPECT_TRUE(NothingToAcquire("w3"));
  TG_ASSERT_OK(scheduler_->Complete("w1", a.key, TrialCompletion(Episodes(0, 2), 2, true, 1)));
  MustAcquire("w3");
}

// A coordinator restart: leases that look expired by the clock are extended
// by one lease timeout, so workers that kept running can reattach.
TEST_F(SchedulerTest, RecoverExtendsOpenLeasesAfterARestart) {
  Submit("s", 1, 2);
  const Lease lease = MustAcquire("w1");
  clock_.AdvanceMs(200'000);  // the coordinator was down for 200 s
  scheduler_ = std::make_unique<Scheduler>(faulty_.get(), &clock_, options_);
  TG_ASSERT_OK_AND_ASSIGN(int extended, scheduler_->Recover());
  EXPECT_EQ(extended, 1);
  TG_ASSERT_OK_AND_ASSIGN(int expired, scheduler_->ExpireLeases());
  EXPECT_EQ(expired, 0);
  TG_ASSERT_OK(scheduler_->Heartbeat("w1", lease.key, {Episodes(0, 2)}));
  TG_ASSERT_OK(scheduler_->Complete("w1", lease.key, TrialCompletion({}, 2, true, 2)));
  EXPECT_EQ(Job(lease.key.job_id).state, JobState::kCompleted);
}

TEST_F(SchedulerTest, RecoveredLeaseStillExpiresIfTheWorkerIsGone) {
  Submit("s", 1, 2);
  const Lease lease = MustAcquire("w1");
  clock_.AdvanceMs(200'000);
  TG_ASSERT_OK(scheduler_->Recover());
  EXPECT_EQ(RunLeaseLoopFor(91'000), 1);
  EXPECT_EQ(Job(lease.key.job_id).state, JobState::kQueued);
}

// Issue 12.2: the coordinator stops (SIGSTOP, swapping) for longer than a
// heartbeat interval. Its workers could not reach it, so when its lease loop
// runs again it extends every open lease, as restart recovery does, instead
// of declaring them all lost at once; leases still expire later if their
// workers really are silent.
TEST_F(SchedulerTest, StallExtendsEveryOpenLeaseBeforeExpiringAny) {
  options_.heartbeat_interval = absl::Seconds(1);
  options_.lease_timeout = absl::Seconds(6);
  scheduler_ = std::make_unique<Scheduler>(faulty_.get(), &clock_, options_);
  Submit("s", 2, 2);
  const Lease a = MustAcquire("w1");
  const Lease b = MustAcquire("w2");
  EXPECT_EQ(RunLeaseLoopFor(2'000, /*step_ms=*/200), 0);
  clock_.AdvanceMs(10'000);  // kill -STOP for 10 s: neither the loop nor the beats run
  ExpiryReport report;
  TG_ASSERT_OK_AND_ASSIGN(int expired, scheduler_->ExpireLeases(&report));
  EXPECT_EQ(expired, 0);
  EXPECT_EQ(report.stalled_ms, 10'000);
  EXPECT_EQ(report.extended, 2);
  EXPECT_EQ(Job(a.key.job_id).state, JobState::kRunning);
  EXPECT_EQ(Job(b.key.job_id).state, JobState::kRunning);
  // After kill -CONT the workers' beats arrive and the leases carry on.
  EXPECT_EQ(RunLeaseLoopFor(500, /*step_ms=*/100), 0);
  TG_ASSERT_OK(scheduler_->Heartbeat("w1", a.key, {Episodes(0, 1)}));
  TG_ASSERT_OK(scheduler_->Heartbeat("w2", b.key, {Episodes(0, 1)}));
  // w1 keeps beating; w2 is really gone: only its lease is lost, 6 s later.
  int lost = 0;
  for (int i = 0; i < 14; ++i) {
    lost += RunLeaseLoopFor(500, /*step_ms=*/100);
    TG_ASSERT_OK(scheduler_->Heartbeat("w1", a.key, {}));
  }
  EXPECT_EQ(lost, 1);
  EXPECT_EQ(Job(a.key.job_id).state, JobState::kRunning);
  EXPECT_EQ(Job(b.key.job_id).state, JobState::kQueued);
}

// Lease deadlines are on the monotonic clock: stepping the wall clock (NTP,
// `date -s`) forward by an hour expires nothing, while time that really
// passes still does.
TEST_F(SchedulerTest, WallClockStepDoesNotExpireLeases) {
  Submit("s", 1, 2);
  const Lease lease = MustAcquire("w1");
  EXPECT_EQ(RunLeaseLoopFor(5'000), 0);
  clock_.StepWallMs(3'600'000);
  EXPECT_EQ(RunLeaseLoopFor(5'000), 0);
  EXPECT_EQ(Job(lease.key.job_id).state, JobState::kRunning);
  clock_.StepWallMs(-7'200'000);  // and backwards
  EXPECT_EQ(RunLeaseLoopFor(91'000), 1);
}

// Leases, heartbeats and completions take no scheduler-wide lock across
// their writes (they decide inside their own transactions), so many workers
// at once share commits; every job still runs once and completes once.
TEST_F(SchedulerTest, ManyWorkersAtOnceCompleteEveryJobOnceAndShareCommits) {
  constexpr int kJobs = 96;
  constexpr int kWorkers = 16;
  Submit("s", kJobs, 2);
  const storage::WriteCounts before = store_->write_counts();
  std::atomic<int> errors{0};
  std::vector<std::thread> workers;
  for (int w = 0; w < kWorkers; ++w) {
    workers.emplace_back([&, w] {
      const std::string id = absl::StrCat("w", w);
      while (true) {
        auto lease = scheduler_->TryAcquire(MakeWorker(id));
        if (!lease.ok()) {
          ++errors;
          return;
        }
        if (!lease->has_value()) return;
        const LeaseKey key = (*lease)->key;
        for (int e = 0; e < 2; ++e) {
          if (!scheduler_->Heartbeat(id, key, {Episodes(e, e + 1)}).ok()) ++errors;
        }
        if (!scheduler_->Complete(id, key, TrialCompletion({}, 2, true, 1)).ok()) ++errors;
      }
    });
  }
  for (std::thread& worker : workers) worker.join();
  EXPECT_EQ(errors.load(), 0);
  TG_ASSERT_OK_AND_ASSIGN(auto jobs, store_->ListJobs({"s", {}, 0, 1000}));
  ASSERT_EQ(jobs.size(), static_cast<size_t>(kJobs));
  for (const JobRecord& job : jobs) {
    EXPECT_EQ(job.state, JobState::kCompleted) << job.id;
    EXPECT_EQ(job.attempts, 1) << job.id;
    EXPECT_EQ(job.episodes_stored, 2) << job.id;
  }
  const storage::WriteCounts after = store_->write_counts();
  EXPECT_LT(after.commits - before.commits, after.writes - before.writes);
}

// A write that fails before commit leaves the job claimable; nothing leaks.
TEST_F(SchedulerTest, StoreFailureBeforeCommitLosesNothing) {
  Submit("s", 1, 2);
  faulty_->FailNext("ClaimJob", absl::UnavailableError("disk hiccup"));
  auto failed = scheduler_->TryAcquire(MakeWorker("w1"));
  EXPECT_EQ(failed.status().code(), absl::StatusCode::kUnavailable);
  const Lease lease = MustAcquire("w1");
  EXPECT_EQ(lease.key.attempt, 1);

  faulty_->FailNext("StoreResults", absl::UnavailableError("disk hiccup"));
  EXPECT_FALSE(scheduler_->Heartbeat("w1", lease.key, {Episodes(0, 1)}).ok());
  EXPECT_EQ(Job(lease.key.job_id).episodes_stored, 0);
  TG_ASSERT_OK(scheduler_->Heartbeat("w1", lease.key, {Episodes(0, 1)}));
  EXPECT_EQ(Job(lease.key.job_id).episodes_stored, 1);
}

// A reply lost after commit: the worker retries and gets OK, not a second effect.
TEST_F(SchedulerTest, LostReplyAfterCommitIsSafeToRetry) {
  Submit("s", 1, 2);
  const Lease lease = MustAcquire("w1");
  TG_ASSERT_OK(scheduler_->Heartbeat("w1", lease.key, {Episodes(0, 2)}));
  faulty_->FailNext("EndAttempt", absl::DeadlineExceededError("reply lost"),
                    FaultyStore::When::kAfterCommit);
  EXPECT_FALSE(scheduler_->Complete("w1", lease.key, TrialCompletion({}, 2, true, 1)).ok());
  TG_ASSERT_OK(scheduler_->Complete("w1", lease.key, TrialCompletion({}, 2, true, 1)));
  EXPECT_EQ(Job(lease.key.job_id).state, JobState::kCompleted);
  EXPECT_EQ(faulty_->faults_fired(), 1);
}

TEST_F(SchedulerTest, BadReportsAreRefusedWithTheFieldNamed) {
  Submit("s", 1, 3);
  const Lease lease = MustAcquire("w1");
  std::vector<Episode> bad = Episodes(0, 1);
  bad[0].real_cost = std::numeric_limits<double>::infinity();
  auto inf = scheduler_->Heartbeat("w1", lease.key, {bad});
  EXPECT_EQ(inf.status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_NE(inf.status().message().find("real_cost is infinite"), std::string::npos);
  bad[0].real_cost = std::nan("");
  EXPECT_EQ(scheduler_->Heartbeat("w1", lease.key, {bad}).status().code(),
            absl::StatusCode::kInvalidArgument);
  auto nan_final = scheduler_->Complete("w1", lease.key, TrialCompletion({}, 3, true, std::nan("")));
  EXPECT_EQ(nan_final.code(), absl::StatusCode::kInvalidArgument);
  auto out_of_range = scheduler_->Heartbeat("w1", lease.key, {Episodes(3, 4)});
  EXPECT_EQ(out_of_range.status().code(), absl::StatusCode::kInvalidArgument);
  EXPECT_EQ(scheduler_->TryAcquire(MakeWorker("")).status().code(),
            absl::StatusCode::kInvalidArgument);
  EXPECT_EQ(scheduler_->Heartbeat("w1", {999, 1}, {}).status().code(), absl::StatusCode::kNotFound);
  // A forged study total is refused before the store counts up to it.
  storage::JobCompletion forged;
  forged.totals.study_cells = 2147483647;
  forged.totals.study_references = 1;
  const absl::Status huge_study = scheduler_->Complete("w1", lease.key, forged);
  EXPECT_EQ(huge_study.code(), absl::StatusCode::kInvalidArgument);
  EXPECT_NE(huge_study.message().find("at most 1000000"), std::string::npos) << huge_study;
  EXPECT_EQ(Job(lease.key.job_id).episodes_stored, 0);
}

// Issue 28: a lease reads the first few candidates and scans further only
// when none of them suits the worker: a worker without study_jobs behind
// more queued studies than that first read still gets the trial after them.
TEST_F(SchedulerTest, AWorkerWithoutStudiesFindsTheTrialBehindManyStudies) {
  storage::NewSweep sweep = MakeSweep("studies-first", 1, 2);
  ASSERT_EQ(sweep.jobs.size(), 1u);
  const storage::NewJob trial = sweep.jobs.front();
  sweep.jobs.clear();
  for (int i = 0; i < 20; ++i) {
    storage::NewJob study = ::totalgrad::testing::MakeStudyJob();
    study.variant = absl::StrCat("study-", i);
    sweep.jobs.push_back(study);
  }
  sweep.jobs.push_back(trial);
  bool created = false;
  TG_ASSERT_OK(scheduler_->SubmitSweep(sweep, &created).status());
  const Lease lease = MustAcquire("w1");
  EXPECT_EQ(lease.job.kind, storage::JobKind::kTrial);
  EXPECT_EQ(lease.job.ordinal, 20);
  EXPECT_TRUE(NothingToAcquire("w1")) << "a worker without study_jobs got a study";
  storage::WorkerIdentity studies = MakeWorker("w2");
  studies.study_jobs = true;
  auto leased = scheduler_->TryAcquire(studies);
  TG_ASSERT_OK(leased.status());
  ASSERT_TRUE(leased->has_value());
  EXPECT_EQ((*leased)->job.kind, storage::JobKind::kStudy);
  EXPECT_EQ((*leased)->job.ordinal, 0);
}

// One Complete for every kind (job_kinds.h): a trial's verdict is the
// worker's (a NaN cost is refused above), a study completes as a success with
// no cost whatever the worker sent, and only a worker that runs studies gets
// one.
TEST_F(SchedulerTest, OneCompleteServesEveryKindAndTheKindDecidesTheVerdict) {
  storage::NewSweep sweep = MakeSweep("kinds", 1, 2);
  sweep.jobs.push_back(::totalgrad::testing::MakeStudyJob());
  bool created = false;
  TG_ASSERT_OK(scheduler_->SubmitSweep(sweep, &created).status());
  const Lease trial = MustAcquire("w1");
  EXPECT_EQ(trial.job.kind, storage::JobKind::kTrial);
  EXPECT_TRUE(NothingToAcquire("w1")) << "a worker without study_jobs got a study";
  storage::WorkerIdentity studies = MakeWorker("w1");
  studies.study_jobs = true;
  auto leased = scheduler_->TryAcquire(studies);
  TG_ASSERT_OK(leased.status());
  ASSERT_TRUE(leased->has_value());
  const Lease lease = **leased;
  EXPECT_EQ(lease.job.kind, storage::JobKind::kStudy);

  storage::JobCompletion rows;
  rows.results.study.cells.resize(2);
  rows.results.study.cells[1].index = 1;
  rows.results.study.references.resize(1);
  rows.totals = {.study_cells = 2, .study_references = 1};
  rows.success = false;                  // an older worker sends no verdict
  rows.final_eval_cost = std::nan("");  // refused for a trial
  TG_ASSERT_OK(scheduler_->Complete("w1", lease.key, rows));
  const JobRecord done = Job(lease.key.job_id);
  EXPECT_EQ(done.state, JobState::kCompleted);
  EXPECT_TRUE(done.success);
  EXPECT_TRUE(std::isnan(done.final_eval_cost));

  TG_ASSERT_OK(scheduler_->Complete("w1", trial.key, TrialCompletion(Episodes(0, 2), 2, false, 31)));
  const JobRecord trial_done = Job(trial.key.job_id);
  EXPECT_EQ(trial_done.state, JobState::kCompleted);
  EXPECT_FALSE(trial_done.success);
  EXPECT_EQ(trial_done.final_eval_cost, 31);
}

// Issue 12.5: a trial that finishes after its sweep was cancelled is stored
// as data (the attempt completed, its episodes kept) but the job stays
// cancelled and counts nowhere as a result; it used to flip to completed.
TEST_F(SchedulerTest, CompletionAfterCancelIsDataButTheJobStaysCancelled) {
  Submit("s", 2, 2);
  const Lease lease = MustAcquire("w1");
  TG_ASSERT_OK(scheduler_->SetSweepState("s", SweepState::kCancelled));
  TG_ASSERT_OK(scheduler_->Complete("w1", lease.key, TrialCompletion(Episodes(0, 2), 2, true, 1)));
  TG_ASSERT_OK(scheduler_->Complete("w1", lease.key, TrialCompletion({}, 2, true, 1)));  // repeated: no-op
  const JobRecord job = Job(lease.key.job_id);
  EXPECT_EQ(job.state, JobState::kCancelled);
  EXPECT_EQ(job.completed_attempt, 0);
  EXPECT_EQ(job.episodes_stored, 2);
  TG_ASSERT_OK_AND_ASSIGN(auto attempts, store_->ListAttempts(lease.key.job_id));
  EXPECT_EQ(attempts[0].state, AttemptState::kCompleted);
  TG_ASSERT_OK_AND_ASSIGN(auto sweep, store_->GetSweep("s"));
  EXPECT_EQ(sweep.jobs_completed, 0);
  EXPECT_EQ(sweep.jobs_cancelled, 2);
  TG_ASSERT_OK_AND_ASSIGN(auto results, store_->ListTrialResults("s"));
  EXPECT_TRUE(results.empty());
}

// Issue 12.5: the job state machine, every (state, event) pair. Each row
// builds its job in a fresh sweep, applies one event, and checks the job's
// next state and the call's status. "tight" sweeps have max_attempts = 1
// and max_lost_leases = 1, so a failure or lost lease is final.
TEST_F(SchedulerTest, JobStateMachineTable) {
  enum class Start { kQueued, kRunning, kCompleted, kFailed, kCancelledIdle, kCancelledOpen };
  enum class Event {
    kAcquire, kHeartbeat, kComplete, kFail, kRelease, kUndelivered, kLeaseLost,
    kCancelSweep, kPauseSweep, kResumeSweep, kRetry
  };
  struct Row {
    Start start;
    bool tight;
    Event event;
    JobState expected;
    absl::StatusCode code;
  };
  using S = JobState;
  using C = absl::StatusCode;
  const std::vector<Row> table = {
      // queued
      {Start::kQueued, false, Event::kAcquire, S::kRunning, C::kOk},
      {Start::kQueued, false, Event::kHeartbeat, S::kQueued, C::kAborted},
      {Start::kQueued, false, Event::kComplete, S::kQueued, C::kAborted},
      {Start::kQueued, false, Event::kFail, S::kQueued, C::kAborted},
      {Start::kQueued, false, Event::kRelease, S::kQueued, C::kAborted},
      {Start::kQueued, false, Event::kUndelivered, S::kQueued, C::kAborted},
      {Start::kQueued, false, Event::kLeaseLost, S::kQueued, C::kOk},
      {Start::kQueued, false, Event::kCancelSweep, S::kCancelled, C::kOk},
      {Start::kQueued, false, Event::kPauseSweep, S::kQueued, C::kOk},
      {Start::kQueued, false, Event::kResumeSweep, S::kQueued, C::kOk},
      {Start::kQueued, false, Event::kRetry, S::kQueued, C::kFailedPrecondition},
      // running, budgets left
      {Start::kRunning, false, Event::kAcquire, S::kRunning, C::kOk},
      {Start::kRunning, false, Event::kHeartbeat, S::kRunning, C::kOk},
      {Start::kRunning, false, Event::kComplete, S::kCompleted, C::kOk},
      {Start::kRunning, false, Event::kFail, S::kQueued, C::kOk},
      {Start::kRunning, false, Event::kRelease, S::kQueued, C::kOk},
      {Start::kRunning, false, Event::kUndelivered, S::kQueued, C::kOk},
      {Start::kRunning, false, Event::kLeaseLost, S::kQueued, C::kOk},
      {Start::kRunning, false, Event::kCancelSweep, S::kCancelled, C::kOk},
      {Start::kRunning, false, Event::kPauseSweep, S::kRunning, C::kOk},
      {Start::kRunning, false, Event::kResumeSweep, S::kRunning, C::kOk},
      {Start::kRunning, false, Event::kRetry, S::kRunning, C::kFailedPrecondition},
      // running, last attempt: the budgets decide
      {Start::kRunning, true, Event::kComplete, S::kCompleted, C::kOk},
      {Start::kRunning, true, Event::kFail, S::kFailed, C::kOk},
      {Start::kRunning, true, Event::kRelease, S::kFailed, C::kOk},
      {Start::kRunning, true, Event::kUndelivered, S::kQueued, C::kOk},  // charges no budget
      {Start::kRunning, true, Event::kLeaseLost, S::kFailed, C::kOk},
      // completed
      {Start::kCompleted, false, Event::kAcquire, S::kCompleted, C::kOk},
      {Start::kCompleted, false, Event::kHeartbeat, S::kCompleted, C::kAborted},
      {Start::kCompleted, false, Event::kComplete, S::kCompleted, C::kOk},  // a repeat
      {Start::kCompleted, false, Event::kFail, S::kCompleted, C::kAborted},
      {Start::kCompleted, false, Event::kRelease, S::kCompleted, C::kAborted},
      {Start::kCompleted, false, Event::kUndelivered, S::kCompleted, C::kAborted},
      {Start::kCompleted, false, Event::kLeaseLost, S::kCompleted, C::kOk},
      {Start::kCompleted, false, Event::kCancelSweep, S::kCompleted, C::kOk},
      {Start::kCompleted, false, Event::kPauseSweep, S::kCompleted, C::kOk},
      {Start::kCompleted, false, Event::kResumeSweep, S::kCompleted, C::kOk},
      {Start::kCompleted, false, Event::kRetry, S::kCompleted, C::kFailedPrecondition},
      // failed (tight sweep, after its one failure)
      {Start::kFailed, true, Event::kAcquire, S::kFailed, C::kOk},
      {Start::kFailed, true, Event::kHeartbeat, S::kFailed, C::kAborted},
      {Start::kFailed, true, Event::kComplete, S::kFailed, C::kAborted},
      {Start::kFailed, true, Event::kFail, S::kFailed, C::kOk},  // a repeat
      {Start::kFailed, true, Event::kRelease, S::kFailed, C::kAborted},
      {Start::kFailed, true, Event::kUndelivered, S::kFailed, C::kAborted},
      {Start::kFailed, true, Event::kLeaseLost, S::kFailed, C::kOk},
      {Start::kFailed, true, Event::kCancelSweep, S::kFailed, C::kOk},
      {Start::kFailed, true, Event::kPauseSweep, S::kFailed, C::kOk},
      {Start::kFailed, true, Event::kResumeSweep, S::kFailed, C::kOk},
      {Start::kFailed, true, Event::kRetry, S::kQueued, C::kOk},
      // cancelled before it ran
      {Start::kCancelledIdle, false, Event::kAcquire, S::kCancelled, C::kOk},
      {Start::kCancelledIdle, false, Event::kHeartbeat, S::kCancelled, C::kAborted},
      {Start::kCancelledIdle, false, Event::kComplete, S::kCancelled, C::kAborted},
      {Start::kCancelledIdle, false, Event::kFail, S::kCancelled, C::kAborted},
      {Start::kCancelledIdle, false, Event::kRelease, S::kCancelled, C::kAborted},
      {Start::kCancelledIdle, false, Event::kUndelivered, S::kCancelled, C::kAborted},
      {Start::kCancelledIdle, false, Event::kLeaseLost, S::kCancelled, C::kOk},
      {Start::kCancelledIdle, false, Event::kCancelSweep, S::kCancelled, C::kOk},
      {Start::kCancelledIdle, false, Event::kPauseSweep, S::kCancelled, C::kFailedPrecondition},
      {Start::kCancelledIdle, false, Event::kResumeSweep, S::kQueued, C::kOk},
      {Start::kCancelledIdle, false, Event::kRetry, S::kQueued, C::kOk},  // runs alone
      // cancelled while its attempt runs: reports are data, the cancel stands
      {Start::kCancelledOpen, false, Event::kAcquire, S::kCancelled, C::kOk},
      {Start::kCancelledOpen, false, Event::kHeartbeat, S::kCancelled, C::kOk},
      {Start::kCancelledOpen, false, Event::kComplete, S::kCancelled, C::kOk},
      {Start::kCancelledOpen, false, Event::kFail, S::kCancelled, C::kOk},
      {Start::kCancelledOpen, false, Event::kRelease, S::kCancelled, C::kOk},
      {Start::kCancelledOpen, false, Event::kUndelivered, S::kCancelled, C::kOk},
      {Start::kCancelledOpen, false, Event::kLeaseLost, S::kCancelled, C::kOk},
      {Start::kCancelledOpen, false, Event::kCancelSweep, S::kCancelled, C::kOk},
      {Start::kCancelledOpen, false, Event::kPauseSweep, S::kCancelled, C::kFailedPrecondition},
      {Start::kCancelledOpen, false, Event::kResumeSweep, S::kRunning, C::kOk},
      {Start::kCancelledOpen, false, Event::kRetry, S::kCancelled, C::kFailedPrecondition},
  };
  int row_number = 0;
  for (const Row& row : table) {
    const std::string sweep = absl::StrCat("row", row_number++);
    SCOPED_TRACE(absl::StrCat(sweep, ": start ", static_cast<int>(row.start), ", event ",
                              static_cast<int>(row.event), ", tight ", row.tight));
    Submit(sweep, 1, 2, row.tight ? 1 : 3, row.tight ? 1 : 20);
    TG_ASSERT_OK_AND_ASSIGN(auto jobs, store_->ListJobs({sweep, {}, 0, 10}));
    const int64_t job_id = jobs.at(0).id;
    LeaseKey key{job_id, 1};  // the attempt the worker calls name (none yet for queued)
    if (row.start != Start::kQueued && row.start != Start::kCancelledIdle) {
      key = MustAcquire("w1").key;
      TG_ASSERT_OK(scheduler_->Heartbeat("w1", key, {Episodes(0, 1)}));
    }
    switch (row.start) {
      case Start::kCompleted:
        TG_ASSERT_OK(scheduler_->Complete("w1", key, TrialCompletion(Episodes(1, 2), 2, true, 1)));
        break;
      case Start::kFailed:
        TG_ASSERT_OK(scheduler_->Fail("w1", key, {}, "boom"));
        break;
      case Start::kCancelledIdle:
      case Start::kCancelledOpen:
        TG_ASSERT_OK(scheduler_->SetSweepState(sweep, SweepState::kCancelled));
        break;
      default:
        break;
    }
    absl::Status status;
    switch (row.event) {
      case Event::kAcquire: status = scheduler_->TryAcquire(MakeWorker("w2")).status(); break;
      case Event::kHeartbeat: status = scheduler_->Heartbeat("w1", key, {}).status(); break;
      case Event::kComplete:
        status = scheduler_->Complete("w1", key, TrialCompletion(Episodes(0, 2), 2, true, 1));
        break;
      case Event::kFail: status = scheduler_->Fail("w1", key, {}, "boom").status(); break;
      case Event::kRelease: status = scheduler_->Release("w1", key, "drain"); break;
      case Event::kUndelivered: status = scheduler_->ReturnUndelivered("w1", key, "gone"); break;
      case Event::kLeaseLost: RunLeaseLoopFor(91'000); break;
      case Event::kCancelSweep:
        status = scheduler_->SetSweepState(sweep, SweepState::kCancelled).status();
        break;
      case Event::kPauseSweep:
        status = scheduler_->SetSweepState(sweep, SweepState::kPaused).status();
        break;
      case Event::kResumeSweep:
        status = scheduler_->SetSweepState(sweep, SweepState::kRunning).status();
        break;
      case Event::kRetry: status = scheduler_->RetryJob(job_id).status(); break;
    }
    EXPECT_EQ(status.code(), row.code) << status;
    EXPECT_EQ(Job(job_id).state, row.expected)
        << "got " << storage::ToString(Job(job_id).state) << ", expected "
        << storage::ToString(row.expected);
    // Leave nothing claimable for the next row's Acquire.
    (void)scheduler_->SetSweepState(sweep, SweepState::kCancelled);
  }
}

// The long poll returns as soon as work appears (bounded real-time wait).
TEST_F(SchedulerTest, AcquireWaitsForWorkAndWakesOnSubmit) {
  std::atomic<bool> got{false};
  const auto start = std::chrono::steady_clock::now();
  std::thread waiter([&] {
    auto lease = scheduler_->Acquire(MakeWorker("w1"), absl::Seconds(20));
    got = lease.ok() && lease->has_value();
  });
  // Submit once the waiter has registered as a worker (it then waits).
  for (int i = 0; i < 2000 && !store_->GetWorker("w1").ok(); ++i) {
    std::this_thread::sleep_for(std::chrono::milliseconds(5));
  }
  Submit("s", 1, 2);
  waiter.join();
  EXPECT_TRUE(got);
  EXPECT_LT(std::chrono::steady_clock::now() - start, std::chrono::seconds(10));
}

TEST_F(SchedulerTest, AcquireReturnsEmptyAtTheDeadlineAndAfterShutdown) {
  auto lease = scheduler_->Acquire(MakeWorker("w1"), absl::Milliseconds(50));
  ASSERT_TRUE(lease.ok());
  EXPECT_FALSE(lease->has_value());
  scheduler_->Shutdown();
  Submit("s", 1, 2);
  const auto start = std::chrono::steady_clock::now();
  lease = scheduler_->Acquire(MakeWorker("w1"), absl::Seconds(20));
  ASSERT_TRUE(lease.ok());
  EXPECT_FALSE(lease->has_value());
  EXPECT_LT(std::chrono::steady_clock::now() - start, std::chrono::seconds(5));
}

// Issue 28.5: a worker's details_json must be JSON (readers parse it): a
// Complete, a Fail or a heartbeat carrying anything else is refused naming
// the episode and details_json, and nothing of it is stored.
TEST_F(SchedulerTest, DetailsJsonThatIsNotJsonIsRefusedNamingIt) {
  Submit("s", 1, 1);
  const Lease lease = MustAcquire("w1");
  std::vector<Episode> episodes = Episodes(0, 1);
  episodes[0].details_json = "{\"cpu_seconds\": 1.5";  // cut short
  auto complete = scheduler_->Complete("w1", lease.key, TrialCompletion(episodes, 1, true, 1.0));
  EXPECT_EQ(complete.code(), absl::StatusCode::kInvalidArgument) << complete;
  EXPECT_NE(complete.message().find("episode 0: details_json is not valid JSON"),
            std::string::npos)
      << complete;
  auto fail = scheduler_->Fail("w1", lease.key, episodes, "boom");
  EXPECT_EQ(fail.status().code(), absl::StatusCode::kInvalidArgument) << fail.status();
  EXPECT_NE(fail.status().message().find("details_json"), std::string::npos) << fail.status();
  EXPECT_EQ(Job(lease.key.job_id).state, JobState::kRunning);
  EXPECT_EQ(Job(lease.key.job_id).episodes_stored, 0);
  // Empty (no details) and any JSON value are fine.
  episodes[0].details_json = "";
  TG_EXPECT_OK(ValidateEpisodes(episodes));
  episodes[0].details_json = "[1, {\"a\": null}]";
  TG_EXPECT_OK(ValidateEpisodes(episodes));
}

// Issue 28.5: an import takes over only what Complete would have accepted:
// a completed trial with a non-finite final cost, an episode with an
// infinite number, details that are not JSON, or a checkpoint without data
// is refused naming the job, and nothing of the archive is stored.
TEST_F(SchedulerTest, ImportRefusesWhatCompleteRefuses) {
  auto archived = [&] {
    storage::ImportedJob job;
    job.record.kind = storage::JobKind::kTrial;
    job.record.method = "RP";
    job.record.seed = "1";
    job.record.variant = "noise_k=1";
    job.record.state = JobState::kCompleted;
    job.record.success = true;
    job.record.final_eval_cost = 2.5;
    job.completed_attempt = 1;
    storage::ImportedAttempt& attempt = job.attempts.emplace_back();
    attempt.attempt = 1;
    attempt.state = AttemptState::kCompleted;
    for (int e = 0; e < 2; ++e) attempt.episodes.emplace_back(MakeEpisode(e), 100 + e);
    return job;
  };
  const storage::NewSweep sweep = MakeSweep("moved", 1, 2);
  auto expect_refused = [&](const storage::ImportedJob& job, const std::string& expected) {
    auto refused = scheduler_->ImportSweep(sweep, "moved", {job}, "a.json");
    EXPECT_EQ(refused.status().code(), absl::StatusCode::kInvalidArgument) << expected;
    EXPECT_NE(refused.status().message().find(expected), std::string::npos) << refused.status();
    EXPECT_NE(refused.status().message().find("archive: job RP seed 1 noise_k=1"),
              std::string::npos)
        << refused.status();
    EXPECT_EQ(store_->GetSweep("moved").status().code(), absl::StatusCode::kNotFound);
  };
  storage::ImportedJob job = archived();
  job.record.final_eval_cost = std::numeric_limits<double>::infinity();
  expect_refused(job, "final_eval_cost that is not finite");
  job = archived();
  job.attempts[0].episodes[1].first.eval_cost_mean = -std::numeric_limits<double>::infinity();
  expect_refused(job, "attempt 1: episode 1: eval_cost_mean is infinite");
  job = archived();
  job.attempts[0].episodes[0].first.details_json = "not json";
  expect_refused(job, "attempt 1: episode 0: details_json is not valid JSON");
  job = archived();
  job.attempts[0].checkpoint = storage::Checkpoint{1, 1, ""};
  expect_refused(job, "attempt 1: checkpoint without data");
  // The same job with its values intact is taken over.
  TG_ASSERT_OK_AND_ASSIGN(storage::ImportResult result,
                          scheduler_->ImportSweep(sweep, "moved", {archived()}, "a.json"));
  EXPECT_EQ(result.jobs_imported, 1);
}

}  // namespace scheduler_test
}  // namespace totalgrad::scheduler
