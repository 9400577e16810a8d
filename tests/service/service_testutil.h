// Helpers for the service tests (status assertions and temporary
// directories: tests/testutil/test_base.h): sweep builders and FaultyStore (a Store wrapper that injects errors, in the
// spirit of leveldb's ErrorEnv).
#ifndef TOTALGRAD_TESTS_SERVICE_SERVICE_TESTUTIL_H_
#define TOTALGRAD_TESTS_SERVICE_SERVICE_TESTUTIL_H_

#include <gtest/gtest.h>

#include <map>
#include <mutex>
#include <string>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "server/storage/store.h"
#include "tests/testutil/test_base.h"  // TG_EXPECT_OK, TG_ASSERT_OK*, MakeTempDir

namespace totalgrad::testing {

// A sweep named `name` with `jobs` jobs (method "RP", seeds 1..jobs, variant
// "noise_k=1"), each expecting `episodes` episodes.
storage::NewSweep MakeSweep(const std::string& name, int jobs, int episodes,
                            const std::string& spec_hash = "hash-1");

// A study job (method "study", seed "7", variant "tiny") carrying `payload`
// as its spec; the store does not read it.
storage::NewJob MakeStudyJob(const std::string& payload = "{}");

storage::Episode MakeEpisode(int episode, double cost = 10.0);

storage::WorkerIdentity MakeWorker(const std::string& id);

// Forwards to a target store; a test arms one failure per method name (e.g.
// "StartAttempt"), which the next call of that method returns instead of
// forwarding (a crash before commit), or after forwarding (committed, but the
// reply was lost).
class FaultyStore final : public storage::Store {
 public:
  explicit FaultyStore(storage::Store* target) : target_(target) {}
  enum class When { kBeforeCommit, kAfterCommit };
  void FailNext(const std::string& method, absl::Status error, When when = When::kBeforeCommit);
  int faults_fired() const;

  absl::StatusOr<storage::SweepRecord> CreateSweep(const storage::NewSweep& sweep, int64_t now_ms,
                                                   bool* created) override;
  absl::Status SetSweepState(const std::string& name, storage::SweepState state,
                             int64_t now_ms) override;
  absl::StatusOr<storage::SweepDiskUse> PruneCheckpoints(const std::string& name,
                                                         storage::PruneScope scope,
                                                         int64_t now_ms) override;
  absl::StatusOr<storage::SweepContents> DeleteSweep(const std::string& name,
                                                     const storage::SweepContents& expected,
                                                     int64_t now_ms) override;
  absl::Status StartAttempt(const storage::LeaseKey& key, const storage::WorkerIdentity& worker,
                            int64_t now_ms, int64_t lease_expires_ms) override;
  absl::StatusOr<std::optional<storage::LeaseKey>> ClaimJob(
      const storage::ClaimRequest& request) override;
  absl::StatusOr<storage::ResultTotals> StoreResults(
      const storage::LeaseKey& key, const std::string& worker_id,
      const storage::JobResults& results, int64_t now_ms,
      std::optional<int64_t> lease_expires_ms) override;
  absl::Status StoreCheckpoint(const storage::LeaseKey& key, const std::string& worker_id,
                               const storage::Checkpoint& checkpoint, int64_t now_ms) override;
  absl::StatusOr<storage::EndOutcome> EndAttempt(const storage::AttemptEnd& end) override;
  absl::StatusOr<int> GrowSweep(const storage::NewSweep& grown, int64_t now_ms) override;
  absl::StatusOr<storage::ImportResult> ImportJobStream(
      const std::optional<storage::NewSweep>& create, const std::string& sweep_name,
      const storage::ImportedJobProducer& jobs, const std::string& source,
      int64_t now_ms) override;
  absl::Status RetryJob(int64_t job_id, int64_t now_ms) override;
  absl::StatusOr<int> SupersedeJob(int64_t job_id, int64_t by_job_id, int64_t now_ms) override;
  absl::StatusOr<int> ExtendOpenLeases(int64_t lease_expires_ms, int64_t now_ms,
                                       const std::string& reason) override;
  absl::Status TouchWorker(const storage::WorkerIdentity& worker, int64_t now_ms) override;
  absl::Status SetWorkerDraining(const std::string& worker_id, bool draining,
                                 int64_t now_ms) override;
  absl::StatusOr<storage::SweepRecord> GetSweep(const std::string& name) override;
  absl::StatusOr<std::vector<storage::SweepRecord>> ListSweeps() override;
  absl::StatusOr<storage::JobRecord> GetJob(int64_t job_id) override;
  absl::StatusOr<storage::JobStatus> GetJobStatus(int64_t job_id) override;
  absl::StatusOr<std::vector<storage::JobRecord>> ListJobs(const storage::JobFilter& f) override;
  absl::StatusOr<std::vector<storage::AttemptRecord>> ListAttempts(int64_t job_id) override;
  absl::StatusOr<std::vector<storage::EventRecord>> ListEvents(int64_t job_id) override;
  absl::StatusOr<std::optional<storage::CheckpointRecord>> GetCheckpoint(int64_t job_id,
                                                                         int attempt) override;
  absl::StatusOr<std::vector<storage::ClaimCandidate>> ListClaimCandidates(int limit) override;
  absl::StatusOr<std::vector<storage::LeaseKey>> ListExpiredLeases(int64_t now_ms) override;
  absl::StatusOr<std::vector<storage::WorkerRecord>> ListWorkers() override;
  absl::StatusOr<storage::WorkerRecord> GetWorker(const std::string& worker_id) override;
  absl::StatusOr<std::vector<results::CompletedTrial>> ListTrialResults(
      const std::string& sweep_name) override;
  absl::Status ExportEpisodes(
      const std::string& sweep_name, bool all_attempts, int batch_size,
      const std::function<absl::Status(std::vector<storage::EpisodeRowRecord>)>& sink) override;
  absl::Status ListStudyRows(const std::string& sweep_name, bool all_attempts,
                             std::vector<storage::StudyCellRecord>* cells,
                             std::vector<storage::StudyReferenceRecord>* references) override;
  absl::StatusOr<storage::StoreCounts> Counts() override;
  absl::StatusOr<int64_t> Backup(const std::string& path) override;

 private:
  struct Fault {
    absl::Status error;
    When when;
  };
  // Pops the armed fault for `method`, if any.
  std::optional<Fault> Take(const std::string& method);

  storage::Store* const target_;
  mutable std::mutex mutex_;
  std::map<std::string, Fault> faults_;
  int fired_ = 0;
};

}  // namespace totalgrad::testing

#endif  // TOTALGRAD_TESTS_SERVICE_SERVICE_TESTUTIL_H_
