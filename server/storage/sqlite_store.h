// SqliteStore: the Store on one SQLite file, owned by the coordinator.
//
// On open: journal_mode=WAL, synchronous=FULL (a commit survives power loss),
// foreign_keys=ON, busy_timeout; the schema is created or checked
// (PRAGMA user_version). Every write is one BEGIN IMMEDIATE transaction on
// the single writer connection; reads use a separate connection and see the
// last committed state (WAL readers never block the writer). Every SQL value
// is a bound parameter.
//
// The file must be on a local disk (SQLite's WAL needs shared memory between
// the connections of one host; never NFS).
#ifndef TOTALGRAD_SERVER_STORAGE_SQLITE_STORE_H_
#define TOTALGRAD_SERVER_STORAGE_SQLITE_STORE_H_

#include <memory>
#include <mutex>
#include <string>

#include "server/storage/sqlite_db.h"
#include "server/storage/store.h"

namespace totalgrad::storage {

struct SqliteStoreOptions {
  // Waited for a lock held by another connection (e.g. a backup), milliseconds.
  int busy_timeout_ms = 5000;
  // Run PRAGMA quick_check on open; DataLoss if it reports a problem.
  bool check_integrity_on_open = true;
};

class SqliteStore final : public Store {
 public:
  // Opens or creates the database at `path`. FailedPrecondition if the file
  // holds a schema of another version or is not a totalgrad database;
  // DataLoss if the integrity check fails.
  static absl::StatusOr<std::unique_ptr<SqliteStore>> Open(const std::string& path,
                                                           const SqliteStoreOptions& options = {});
  ~SqliteStore() override;

  const std::string& path() const { return path_; }
  // The writer connection's settings, e.g.
  // "journal_mode=wal synchronous=2 foreign_keys=1 busy_timeout=5000" (logged
  // on start; tests check them).
  absl::StatusOr<std::string> DescribeSettings();
  // A trivial read (the schema table) on the reader connection: OK if the
  // database answers. For the coordinator's health endpoint.
  absl::Status Ping();

  absl::StatusOr<SweepRecord> CreateSweep(const NewSweep& sweep, int64_t now_ms,
                                          bool* created) override;
  absl::Status SetSweepState(const std::string& name, SweepState state, int64_t now_ms) override;
  absl::Status StartAttempt(const LeaseKey& key, const WorkerIdentity& worker, int64_t now_ms,
                            int64_t lease_expires_ms) override;
  absl::StatusOr<int> StoreEpisodes(const LeaseKey& key, const std::string& worker_id,
                                    const std::vector<Episode>& episodes, int64_t now_ms,
                                    std::optional<int64_t> lease_expires_ms) override;
  absl::StatusOr<int> StoreStudyRows(const LeaseKey& key, const std::string& worker_id,
                                     const StudyRows& rows, int64_t now_ms,
                                     std::optional<int64_t> lease_expires_ms) override;
  absl::StatusOr<EndOutcome> EndAttempt(const AttemptEnd& end) override;
  absl::Status RetryJob(int64_t job_id, int64_t now_ms) override;
  absl::StatusOr<int> ExtendOpenLeases(int64_t lease_expires_ms, int64_t now_ms,
                                       const std::string& reason) override;
  absl::Status TouchWorker(const WorkerIdentity& worker, int64_t now_ms) override;
  absl::Status SetWorkerDraining(const std::string& worker_id, bool draining,
                                 int64_t now_ms) override;

  absl::StatusOr<SweepRecord> GetSweep(const std::string& name) override;
  absl::StatusOr<std::vector<SweepRecord>> ListSweeps() override;
  absl::StatusOr<JobRecord> GetJob(int64_t job_id) override;
  absl::StatusOr<std::vector<JobRecord>> ListJobs(const JobFilter& filter) override;
  absl::StatusOr<std::vector<AttemptRecord>> ListAttempts(int64_t job_id) override;
  absl::StatusOr<std::vector<EventRecord>> ListEvents(int64_t job_id) override;
  absl::StatusOr<std::vector<ClaimCandidate>> ListClaimCandidates(int limit) override;
  absl::StatusOr<std::vector<LeaseKey>> ListExpiredLeases(int64_t now_ms) override;
  absl::StatusOr<std::vector<WorkerRecord>> ListWorkers() override;
  absl::StatusOr<WorkerRecord> GetWorker(const std::string& worker_id) override;
  absl::StatusOr<std::vector<TrialResultRecord>> ListTrialResults(
      const std::string& sweep_name) override;
  absl::Status ExportEpisodes(
      const std::string& sweep_name, bool all_attempts, int batch_size,
      const std::function<absl::Status(std::vector<EpisodeRowRecord>)>& sink) override;
  absl::Status ListStudyRows(const std::string& sweep_name, bool all_attempts,
                             std::vector<StudyCellRecord>* cells,
                             std::vector<StudyReferenceRecord>* references) override;
  absl::StatusOr<StoreCounts> Counts() override;
  absl::StatusOr<int64_t> Backup(const std::string& path) override;

 private:
  SqliteStore(std::string path, SqliteStoreOptions options, internal::Db writer,
              internal::Db reader);
  // Runs `body` inside BEGIN IMMEDIATE ... COMMIT on the writer; rolls back
  // if `body` or the commit fails.
  absl::Status InWriteTransaction(const std::function<absl::Status(internal::Db&)>& body);

  const std::string path_;
  const SqliteStoreOptions options_;
  std::mutex write_mutex_;
  internal::Db writer_;  // guarded by write_mutex_
  std::mutex read_mutex_;
  internal::Db reader_;  // guarded by read_mutex_
};

}  // namespace totalgrad::storage

#endif  // TOTALGRAD_SERVER_STORAGE_SQLITE_STORE_H_
