// SqliteStore: the Store on one SQLite file, owned by the coordinator.
//
// On open: journal_mode=WAL, synchronous=FULL (a commit survives power loss),
// foreign_keys=ON, busy_timeout; the schema is created or checked
// (PRAGMA user_version). Writes go through the single writer connection
// with group commit: writes that arrive while one commits queue, and the
// next transaction (BEGIN IMMEDIATE ... COMMIT, one fsync) carries all of
// them, each inside a savepoint of its own, so one write's failure undoes
// only that write. No write returns before the COMMIT that holds it is
// durable, so an acknowledged write survives kill -9 and power loss as
// before; a write that fails is not stored. Reads use a separate connection
// and see the last committed state (WAL readers never block the writer).
// Every SQL value is a bound parameter.
//
// The file must be on a local disk (SQLite's WAL needs shared memory between
// the connections of one host; never NFS).
//
// Ownership: Open takes an exclusive flock on "<path>.lock" (not SQLite's
// exclusive locking mode, so read-only readers of the WAL database keep
// working) and writes the holder (pid, host, time) and the database's
// device:inode into it; a second SqliteStore on the same file, in this
// process or another, is refused naming the holder. The lock file stays when
// the store closes: its record of the database is how a later Open knows
// that a missing database file was deleted rather than never created.
//
// Safety of the file (checked before anything is written to it):
//   * missing, with no lock file recording a database: a new store (first start);
//   * missing although the lock file records one, a 0-byte file, or an SQLite
//     file with no tables: refused unless options.init;
//   * anything else that is not a totalgrad database (other SQLite tables, or
//     not SQLite at all): refused, even with init;
//   * a newer schema version: refused, and the file is left byte for byte as
//     it was (it is inspected through a read-only connection first).
// While open, every write first checks that the path still names the file
// that was opened (device and inode); once it was deleted or replaced every
// write is refused with Unavailable naming the problem, so nothing more is
// acknowledged that a restart would lose.
#ifndef TOTALGRAD_SERVER_STORAGE_SQLITE_STORE_H_
#define TOTALGRAD_SERVER_STORAGE_SQLITE_STORE_H_

#include <atomic>
#include <cstdint>
#include <deque>
#include <functional>
#include <memory>
#include <string>
#include <vector>

#include "absl/base/thread_annotations.h"
#include "absl/synchronization/mutex.h"
#include "server/storage/sqlite_db.h"
#include "server/storage/store.h"

namespace totalgrad::storage {

// How long the health check waits for SQLite's write lock, and how long a
// write may have waited for it before the check reports the store as not
// writable (milliseconds).
inline constexpr int64_t kWriteLockWaitReportMs = 300;

struct SqliteStoreOptions {
  // Waited for a lock held by another connection (e.g. a backup), milliseconds.
  int busy_timeout_ms = 5000;
  // Run PRAGMA quick_check on open; DataLoss if it reports a problem.
  bool check_integrity_on_open = true;
  // May initialise a new store in a 0-byte file, an SQLite file without
  // tables, or where the lock file says a database existed that is now
  // missing (the coordinator's --init).
  bool init = false;
  // PRAGMA max_page_count of the writer after open (0: SQLite's default):
  // makes commits that grow the file fail as on a full disk (tests).
  int64_t max_page_count = 0;
};

// What the writer has committed since the store was opened: `writes`
// bodies in `commits` transactions (writes / commits is the mean group).
struct WriteCounts {
  int64_t writes = 0;
  int64_t commits = 0;
};

class SqliteStore final : public Store {
 public:
  // Writes that one transaction carries at the most: bounds how long a
  // queued write waits behind others in the same commit.
  static constexpr int kMaxWritesPerCommit = 256;

  // Opens or creates the database at `path` (see the rules above).
  // FailedPrecondition naming the problem: another store holds the lock (its
  // pid and host named), the file is missing/empty without init, foreign, or
  // of a newer schema version; DataLoss if the integrity check fails.
  static absl::StatusOr<std::unique_ptr<SqliteStore>> Open(const std::string& path,
                                                           const SqliteStoreOptions& options = {});
  // Opens an existing database for reading only (`totalgrad results --db`):
  // no lock is taken, so this works beside the coordinator that owns the file
  // (SQLite's WAL lets readers run while it commits), and nothing is ever
  // written: every write returns FailedPrecondition. FailedPrecondition for a
  // file that is missing, not a totalgrad database, or of another schema
  // version (the message says how to migrate it); DataLoss if it is corrupt.
  static absl::StatusOr<std::unique_ptr<SqliteStore>> OpenReadOnly(const std::string& path);
  // Writes a consistent copy of the database at `path` to `target` (which
  // must not exist) through a read-only connection: no lock is taken, so
  // this works while a coordinator owns the file, and nothing is written to
  // it. Refuses (FailedPrecondition) what Open would refuse as foreign or
  // too new. Returns the copy's size in bytes.
  static absl::StatusOr<int64_t> BackupFile(const std::string& path, const std::string& target);
  ~SqliteStore() override;

  const std::string& path() const { return path_; }
  // The writer connection's settings, e.g.
  // "journal_mode=wal synchronous=2 foreign_keys=1 busy_timeout=5000" (logged
  // on start; tests check them).
  absl::StatusOr<std::string> DescribeSettings();
  // A trivial read (the schema table) on the reader connection: OK if the
  // database answers. For the coordinator's health endpoint.
  absl::Status Ping();
  // Whether writes can be acknowledged: Unavailable naming the reason if the
  // database file was deleted or replaced, or if the last write transaction
  // failed in the database (a full or failing disk) and no commit has
  // succeeded since. Without a successful commit in the last 5 s it commits
  // a tiny probe (the `meta` table) to find out; after a failure at most one
  // probe per 5 s. Answers within about kWriteLockWaitReportMs, never
  // queueing behind a write: Unavailable when another process or connection
  // holds SQLite's write lock (a write waiting that long for it, or the
  // probe's own wait). For the coordinator's health endpoint.
  absl::Status CheckWritable() ABSL_LOCKS_EXCLUDED(write_mutex_);
  // Counts of committed writes and transactions (benchmarks and tests).
  WriteCounts write_counts() ABSL_LOCKS_EXCLUDED(write_mutex_);

  absl::StatusOr<SweepRecord> CreateSweep(const NewSweep& sweep, int64_t now_ms,
                                          bool* created) override;
  absl::Status SetSweepState(const std::string& name, SweepState state, int64_t now_ms) override;
  absl::StatusOr<SweepDiskUse> PruneCheckpoints(const std::string& name, PruneScope scope,
                                                int64_t now_ms) override;
  absl::StatusOr<SweepContents> DeleteSweep(const std::string& name,
                                            const SweepContents& expected,
                                            int64_t now_ms) override;
  absl::Status StartAttempt(const LeaseKey& key, const WorkerIdentity& worker, int64_t now_ms,
                            int64_t lease_expires_ms) override;
  absl::StatusOr<std::optional<LeaseKey>> ClaimJob(const ClaimRequest& request) override;
  absl::StatusOr<ResultTotals> StoreResults(const LeaseKey& key, const std::string& worker_id,
                                            const JobResults& results, int64_t now_ms,
                                            std::optional<int64_t> lease_expires_ms) override;
  absl::Status StoreCheckpoint(const LeaseKey& key, const std::string& worker_id,
                               const Checkpoint& checkpoint, int64_t now_ms) override;
  absl::StatusOr<EndOutcome> EndAttempt(const AttemptEnd& end) override;
  absl::StatusOr<int> GrowSweep(const NewSweep& grown, int64_t now_ms) override;
  absl::StatusOr<ImportResult> ImportJobStream(const std::optional<NewSweep>& create,
                                               const std::string& sweep_name,
                                               const ImportedJobProducer& jobs,
                                               const std::string& source,
                                               int64_t now_ms) override;
  absl::Status RetryJob(int64_t job_id, int64_t now_ms) override;
  absl::StatusOr<int> SupersedeJob(int64_t job_id, int64_t by_job_id, int64_t now_ms) override;
  absl::StatusOr<int> ExtendOpenLeases(int64_t lease_expires_ms, int64_t now_ms,
                                       const std::string& reason) override;
  absl::Status TouchWorker(const WorkerIdentity& worker, int64_t now_ms) override;
  absl::Status SetWorkerDraining(const std::string& worker_id, bool draining,
                                 int64_t now_ms) override;

  absl::StatusOr<SweepRecord> GetSweep(const std::string& name) override;
  absl::StatusOr<std::vector<SweepRecord>> ListSweeps() override;
  absl::StatusOr<JobRecord> GetJob(int64_t job_id) override;
  absl::StatusOr<JobStatus> GetJobStatus(int64_t job_id) override;
  absl::StatusOr<std::vector<JobRecord>> ListJobs(const JobFilter& filter) override;
  absl::StatusOr<std::vector<AttemptRecord>> ListAttempts(int64_t job_id) override;
  absl::StatusOr<std::vector<EventRecord>> ListEvents(int64_t job_id) override;
  absl::StatusOr<std::optional<CheckpointRecord>> GetCheckpoint(int64_t job_id,
                                                                int attempt) override;
  absl::StatusOr<std::vector<ClaimCandidate>> ListClaimCandidates(int limit) override;
  absl::StatusOr<std::vector<LeaseKey>> ListExpiredLeases(int64_t now_ms) override;
  absl::StatusOr<std::vector<WorkerRecord>> ListWorkers() override;
  absl::StatusOr<WorkerRecord> GetWorker(const std::string& worker_id) override;
  absl::StatusOr<std::vector<results::CompletedTrial>> ListTrialResults(
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
              internal::Db reader, int lock_fd, uint64_t device, uint64_t inode);
  friend class SqliteStoreTestPeer;
  struct QueuedWrite;
  // Runs `body` on the writer inside a write transaction and returns once
  // that transaction committed (OK) or `body`'s changes were undone (the
  // error). The transaction may carry other queued writes (group commit,
  // above); `body` runs on whichever thread commits the group, so it must
  // not depend on its thread, and it may see earlier writes of its group.
  // Refuses at once once the file was deleted or replaced; records database
  // failures for CheckWritable.
  absl::Status InWriteTransaction(const std::function<absl::Status(internal::Db&)>& body)
      ABSL_LOCKS_EXCLUDED(write_mutex_, queue_mutex_);
  // Runs `group` (the front of write_queue_) in one transaction and sets each
  // write's status.
  void CommitGroupLocked(const std::vector<QueuedWrite*>& group)
      ABSL_EXCLUSIVE_LOCKS_REQUIRED(write_mutex_);
  // BEGIN IMMEDIATE, timed for CheckWritable; SQLite's busy answer becomes
  // Unavailable naming the lock holder's role (*lock_busy true).
  absl::Status BeginLocked(bool* lock_busy) ABSL_EXCLUSIVE_LOCKS_REQUIRED(write_mutex_);
  absl::Status CheckWritableLocked() ABSL_EXCLUSIVE_LOCKS_REQUIRED(write_mutex_);
  // Unavailable (and remembered) if `path_` no longer names the opened file.
  absl::Status CheckFileIdentityLocked() ABSL_EXCLUSIVE_LOCKS_REQUIRED(write_mutex_);

  const std::string path_;
  const SqliteStoreOptions options_;
  const int lock_fd_;  // -1: opened read-only, no lock held
  const uint64_t device_;
  const uint64_t inode_;
  absl::Mutex write_mutex_;
  internal::Db writer_ ABSL_GUARDED_BY(write_mutex_);
  // The file was deleted or replaced (sticky); the last database failure of
  // a write and when it (or the last probe) was, and when a commit last
  // succeeded (steady clock, ms).
  absl::Status file_error_ ABSL_GUARDED_BY(write_mutex_);
  absl::Status last_write_error_ ABSL_GUARDED_BY(write_mutex_);
  int64_t last_failure_or_probe_ms_ ABSL_GUARDED_BY(write_mutex_) = 0;
  int64_t last_commit_ms_ ABSL_GUARDED_BY(write_mutex_) = 0;
  // When the running write transaction started waiting for SQLite's write
  // lock (steady clock, ms); 0 when none is waiting. Read without the mutex
  // by CheckWritable, which must not queue behind that wait.
  std::atomic<int64_t> lock_wait_since_ms_{0};
  WriteCounts write_counts_ ABSL_GUARDED_BY(write_mutex_);
  // Writes waiting for a transaction, oldest first; the front one's thread
  // commits the group (leveldb's writer queue).
  absl::Mutex queue_mutex_ ABSL_ACQUIRED_BEFORE(write_mutex_);
  std::deque<QueuedWrite*> write_queue_ ABSL_GUARDED_BY(queue_mutex_);
  absl::Mutex read_mutex_;
  internal::Db reader_ ABSL_GUARDED_BY(read_mutex_);
};

}  // namespace totalgrad::storage

#endif  // TOTALGRAD_SERVER_STORAGE_SQLITE_STORE_H_
