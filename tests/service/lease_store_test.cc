// The store's lease decisions taken inside their own transactions (so that
// leases, heartbeats and ends can run beside each other and share commits):
// ClaimJob picks and opens a job in one transaction; an end decided by
// AttemptEnd::decide sees the job as it is when the end is written; the
// lease expiry's end leaves a lease that a heartbeat extended meanwhile.
#include <gtest/gtest.h>

#include <algorithm>
#include <atomic>
#include <filesystem>
#include <map>
#include <set>
#include <thread>
#include <vector>

#include "server/storage/sqlite_store.h"
#include "tests/service/service_testutil.h"
#include "tests/service/store_fixture.h"

namespace totalgrad::storage {
namespace {

using ::totalgrad::testing::MakeEpisode;
using ::totalgrad::testing::MakeSweep;
using ::totalgrad::testing::MakeWorker;

constexpr int64_t kNow = 1'000'000;
constexpr int64_t kLeaseEnd = kNow + 90'000;

class LeaseStoreTest : public ::totalgrad::testing::FreshStoreTest {
 protected:
  void Submit(const std::string& name, int jobs, int episodes) {
    bool created = false;
    TG_ASSERT_OK(store_->CreateSweep(MakeSweep(name, jobs, episodes), kNow, &created).status());
  }
  ClaimRequest Request(const std::string& worker_id) {
    ClaimRequest request;
    request.worker = MakeWorker(worker_id);
    request.now_ms = kNow;
    request.lease_expires_ms = kLeaseEnd;
    return request;
  }
  // An end of attempt `key` by "w1" whose job state AttemptEnd::decide sets
  // from the job as the end's transaction sees it.
  AttemptEnd DecidedEnd(const LeaseKey& key, AttemptState state, JobState* seen) {
    AttemptEnd end;
    end.key = key;
    end.worker_id = "w1";
    end.attempt_state = state;
    end.now_ms = kNow;
    end.decide = [seen](const JobStatus& job, AttemptEnd* decided) {
      *seen = job.state;
      decided->job_state =
          job.state == JobState::kCancelled ? JobState::kCancelled : JobState::kQueued;
      return absl::OkStatus();
    };
    return end;
  }
};

TEST_F(LeaseStoreTest, AClaimOpensTheFirstQueuedJobAndRecordsTheWorker) {
  Submit("s", 3, 2);
  TG_ASSERT_OK_AND_ASSIGN(std::optional<LeaseKey> key, store_->ClaimJob(Request("w1")));
  ASSERT_TRUE(key.has_value());
  TG_ASSERT_OK_AND_ASSIGN(auto jobs, store_->ListJobs({"s", {}, 0, 10}));
  ASSERT_EQ(jobs.size(), 3u);
  EXPECT_EQ(key->job_id, jobs[0].id);
  EXPECT_EQ(key->attempt, 1);
  EXPECT_EQ(jobs[0].state, JobState::kRunning);
  EXPECT_EQ(jobs[0].worker_id, "w1");
  EXPECT_EQ(jobs[1].state, JobState::kQueued);
  TG_ASSERT_OK_AND_ASSIGN(WorkerRecord worker, store_->GetWorker("w1"));
  EXPECT_EQ(worker.last_seen_ms, kNow);
}

TEST_F(LeaseStoreTest, AClaimSkipsWhatDoesNotSuitAndStillRecordsTheWorker) {
  Submit("s", 3, 2);
  ClaimRequest request = Request("w2");
  TG_ASSERT_OK_AND_ASSIGN(auto jobs, store_->ListJobs({"s", {}, 0, 10}));
  const int64_t refused = jobs[0].id;
  request.suits = [refused](const ClaimCandidate& c) { return c.job_id != refused; };
  TG_ASSERT_OK_AND_ASSIGN(std::optional<LeaseKey> key, store_->ClaimJob(request));
  ASSERT_TRUE(key.has_value());
  EXPECT_EQ(key->job_id, jobs[1].id);
  // Nothing suits: no lease, but the worker was heard from.
  request = Request("w3");
  request.suits = [](const ClaimCandidate&) { return false; };
  TG_ASSERT_OK_AND_ASSIGN(key, store_->ClaimJob(request));
  EXPECT_FALSE(key.has_value());
  TG_EXPECT_OK(store_->GetWorker("w3").status());
  TG_ASSERT_OK_AND_ASSIGN(jobs, store_->ListJobs({"s", {}, 0, 10}));
  EXPECT_EQ(jobs[0].state, JobState::kQueued);
  EXPECT_EQ(jobs[2].state, JobState::kQueued);
}

TEST_F(LeaseStoreTest, AClaimLooksPastTheFirstScanOnlyWhenNoneOfItSuits) {
  Submit("s", 12, 2);
  TG_ASSERT_OK_AND_ASSIGN(auto jobs, store_->ListJobs({"s", {}, 0, 20}));
  ClaimRequest request = Request("w1");
  request.first_scan = 4;
  request.scan_limit = 12;
  const int64_t wanted = jobs[9].id;  // beyond the first four
  request.suits = [wanted](const ClaimCandidate& c) { return c.job_id == wanted; };
  TG_ASSERT_OK_AND_ASSIGN(std::optional<LeaseKey> key, store_->ClaimJob(request));
  ASSERT_TRUE(key.has_value());
  EXPECT_EQ(key->job_id, wanted);
}

TEST_F(LeaseStoreTest, ClaimsFromManyThreadsLeaseEveryJobExactlyOnce) {
  constexpr int kJobs = 120;
  constexpr int kThreads = 12;
  Submit("s", kJobs, 2);
  std::vector<std::vector<LeaseKey>> claimed(kThreads);
  std::atomic<int> errors{0};
  std::vector<std::thread> threads;
  for (int t = 0; t < kThreads; ++t) {
    threads.emplace_back([&, t] {
      while (true) {
        absl::StatusOr<std::optional<LeaseKey>> key =
            store_->ClaimJob(Request("w" + std::to_string(t)));
        if (!key.ok()) {
          ++errors;
          return;
        }
        if (!key->has_value()) return;
        claimed[t].push_back(**key);
      }
    });
  }
  for (std::thread& thread : threads) thread.join();
  EXPECT_EQ(errors.load(), 0);
  std::set<int64_t> jobs;
  for (const auto& keys : claimed) {
    for (const LeaseKey& key : keys) {
      EXPECT_EQ(key.attempt, 1);
      EXPECT_TRUE(jobs.insert(key.job_id).second) << "job " << key.job_id << " leased twice";
    }
  }
  EXPECT_EQ(jobs.size(), static_cast<size_t>(kJobs));
}

TEST_F(LeaseStoreTest, AnEndIsDecidedOnTheJobAsItIsWhenTheEndIsWritten) {
  Submit("s", 1, 2);
  TG_ASSERT_OK_AND_ASSIGN(std::optional<LeaseKey> key, store_->ClaimJob(Request("w1")));
  ASSERT_TRUE(key.has_value());
  // The sweep is cancelled after the worker's lease and before its release.
  TG_ASSERT_OK(store_->SetSweepState("s", SweepState::kCancelled, kNow));
  JobState seen = JobState::kQueued;
  TG_ASSERT_OK_AND_ASSIGN(EndOutcome outcome,
                          store_->EndAttempt(DecidedEnd(*key, AttemptState::kReleased, &seen)));
  EXPECT_EQ(outcome, EndOutcome::kApplied);
  EXPECT_EQ(seen, JobState::kCancelled);
  TG_ASSERT_OK_AND_ASSIGN(JobRecord job, store_->GetJob(key->job_id));
  EXPECT_EQ(job.state, JobState::kCancelled);
}

TEST_F(LeaseStoreTest, ADecisionThatRefusesChangesNothing) {
  Submit("s", 1, 2);
  TG_ASSERT_OK_AND_ASSIGN(std::optional<LeaseKey> key, store_->ClaimJob(Request("w1")));
  ASSERT_TRUE(key.has_value());
  AttemptEnd end;
  end.key = *key;
  end.worker_id = "w1";
  end.attempt_state = AttemptState::kReleased;
  end.results.episodes = {MakeEpisode(0)};
  end.now_ms = kNow;
  end.decide = [](const JobStatus&, AttemptEnd*) {
    return absl::FailedPreconditionError("refused by the decision");
  };
  EXPECT_EQ(store_->EndAttempt(end).status().code(), absl::StatusCode::kFailedPrecondition);
  TG_ASSERT_OK_AND_ASSIGN(JobRecord job, store_->GetJob(key->job_id));
  EXPECT_EQ(job.state, JobState::kRunning);
  EXPECT_EQ(job.episodes_stored, 0);
}

TEST_F(LeaseStoreTest, TheExpiryLeavesALeaseThatAHeartbeatExtendedAfterItWasRead) {
  Submit("s", 1, 3);
  TG_ASSERT_OK_AND_ASSIGN(std::optional<LeaseKey> key, store_->ClaimJob(Request("w1")));
  ASSERT_TRUE(key.has_value());
  const int64_t expiry_now = kLeaseEnd + 1;
  TG_ASSERT_OK_AND_ASSIGN(std::vector<LeaseKey> expired, store_->ListExpiredLeases(expiry_now));
  ASSERT_EQ(expired.size(), 1u);
  // The heartbeat commits between the expiry's read and its end.
  TG_ASSERT_OK(store_->StoreResults(*key, "w1", {{MakeEpisode(0)}}, expiry_now,
                                    expiry_now + 90'000)
                   .status());
  JobState seen = JobState::kQueued;
  AttemptEnd lost = DecidedEnd(*key, AttemptState::kLeaseLost, &seen);
  lost.only_if_lease_expires_before_ms = expiry_now;
  TG_ASSERT_OK_AND_ASSIGN(EndOutcome outcome, store_->EndAttempt(lost));
  EXPECT_EQ(outcome, EndOutcome::kLeaseRenewed);
  TG_ASSERT_OK_AND_ASSIGN(JobRecord job, store_->GetJob(key->job_id));
  EXPECT_EQ(job.state, JobState::kRunning);
  EXPECT_EQ(job.lost_leases, 0);
  // Without the heartbeat the same end applies.
  TG_ASSERT_OK_AND_ASSIGN(expired, store_->ListExpiredLeases(expiry_now + 90'001));
  ASSERT_EQ(expired.size(), 1u);
  lost.only_if_lease_expires_before_ms = expiry_now + 90'001;
  TG_ASSERT_OK_AND_ASSIGN(outcome, store_->EndAttempt(lost));
  EXPECT_EQ(outcome, EndOutcome::kApplied);
  TG_ASSERT_OK_AND_ASSIGN(job, store_->GetJob(key->job_id));
  EXPECT_EQ(job.state, JobState::kQueued);
}

}  // namespace
}  // namespace totalgrad::storage
