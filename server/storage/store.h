// The coordinator's durable state: sweeps, jobs, attempts (= leases),
// episodes, workers and an event log (their records: store_records.h). The
// schema is documented in docs/results_schema.md.
//
// Store is an interface (leveldb's DB/Env seam) so tests can wrap it, e.g.
// with a fault-injecting store, made of three by their users: LeaseStore
// (the scheduler's leasing), SweepAdministration (submission and the sweep
// and job commands) and StoreReader (the dashboard, results and --db reads).
// SqliteStore (sqlite_store.h) is the real one and implements all three.
//
// Contract shared by every write:
//   * It is one transaction: when it returns OK the change is committed
//     durably; when it returns an error nothing changed.
//   * It takes `now_ms` from the caller (the coordinator's clock); the store
//     never reads a clock itself.
//   * Fenced writes name a lease (job id + attempt). If that attempt is not
//     the job's open attempt they return ABORTED and change nothing.
// Errors common to all calls: Unavailable (database busy), DataLoss
// (corruption), Internal (other SQLite errors).
//
// Threading: implementations are safe to call from many threads. Writes are
// serialised (one writer); reads may run concurrently with a write and see
// the last committed state.
#ifndef TOTALGRAD_SERVER_STORAGE_STORE_H_
#define TOTALGRAD_SERVER_STORAGE_STORE_H_

#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "server/storage/store_records.h"

namespace totalgrad::storage {

// What leasing needs (the scheduler): the next jobs to run, attempts opened,
// fed, checkpointed and ended under their lease, expired leases, workers.
class LeaseStore {
 public:
  virtual ~LeaseStore() = default;

  // The fields of job `job_id` that the scheduler decides on, without its
  // options, its episode count or its worker (GetJob reads and parses those:
  // they were about half of the coordinator's CPU per job when heartbeats
  // and completions read them; issue 28). NotFound if no such job.
  virtual absl::StatusOr<JobStatus> GetJobStatus(int64_t job_id) = 0;

  // Opens attempt `key.attempt` of a queued job for `worker`: the job becomes
  // running with attempts = key.attempt. FailedPrecondition (nothing changed)
  // unless the job is queued with attempts == key.attempt - 1.
  virtual absl::Status StartAttempt(const LeaseKey& key, const WorkerIdentity& worker,
                                    int64_t now_ms, int64_t lease_expires_ms) = 0;

  // Stores result rows of an open attempt owned by `worker_id` (a row whose
  // key is already stored is ignored: replays are harmless) and, if given,
  // moves its lease expiry. Returns how many rows of each of the kind's
  // tables are stored for the attempt (0 for the tables it does not own).
  // Aborted: stale lease or another worker's; InvalidArgument: rows of a
  // table the job's kind does not own (naming the kind and the table), an
  // episode outside [0, episodes_expected), a negative study row index.
  virtual absl::StatusOr<ResultTotals> StoreResults(const LeaseKey& key,
                                                    const std::string& worker_id,
                                                    const JobResults& results, int64_t now_ms,
                                                    std::optional<int64_t> lease_expires_ms) = 0;

  // Keeps `checkpoint` as the latest state of an open trial attempt owned by
  // `worker_id`, unless the attempt already has one of a later episode (a
  // replay). Aborted: stale lease or another worker's; InvalidArgument: a
  // job whose kind keeps no checkpoints (studies), or an episode outside
  // [0, episodes_expected).
  virtual absl::Status StoreCheckpoint(const LeaseKey& key, const std::string& worker_id,
                                       const Checkpoint& checkpoint, int64_t now_ms) = 0;

  // Ends an attempt as `end` says. Aborted if the attempt is not open (unless
  // it already ended with the same attempt state: kAlreadyEnded), or belongs
  // to another worker. For kCompleted, the kind's completion check
  // (job_kinds.h) with one missing-rows query per result table: the totals
  // must pass the kind's rule (InvalidArgument otherwise, and for a total of
  // a table the kind does not own), then FailedPrecondition names the
  // missing rows of the first table that lacks some of 0..total-1 (nothing
  // changes).
  virtual absl::StatusOr<EndOutcome> EndAttempt(const AttemptEnd& end) = 0;

  // Sets the lease expiry of every open attempt to at least `lease_expires_ms`
  // (coordinator start-up or after a stall, so running workers can reattach);
  // `reason` goes into the event log. Returns how many.
  virtual absl::StatusOr<int> ExtendOpenLeases(int64_t lease_expires_ms, int64_t now_ms,
                                               const std::string& reason) = 0;

  // Inserts or refreshes a worker (host, build, slots, last seen).
  virtual absl::Status TouchWorker(const WorkerIdentity& worker, int64_t now_ms) = 0;

  // NotFound if the worker was never seen.
  virtual absl::Status SetWorkerDraining(const std::string& worker_id, bool draining,
                                         int64_t now_ms) = 0;

  // The lease as one transaction: refreshes the worker (TouchWorker) and
  // opens the next attempt (StartAttempt) of the first claimable job that
  // suits it (ListClaimCandidates' order; request.suits). The candidates are read inside the transaction, so leases
  // that run beside each other never take the same job nor skip one.
  // nullopt: nothing claimable suits the worker (it is still refreshed).
  virtual absl::StatusOr<std::optional<LeaseKey>> ClaimJob(const ClaimRequest& request) = 0;

  // Queued jobs of running sweeps, oldest sweep first then ordinal; at most
  // `limit`. A sweep already running max_concurrent jobs contributes none.
  virtual absl::StatusOr<std::vector<ClaimCandidate>> ListClaimCandidates(int limit) = 0;

  // Open attempts whose lease expired before `now_ms`.
  virtual absl::StatusOr<std::vector<LeaseKey>> ListExpiredLeases(int64_t now_ms) = 0;
};

// What changes sweeps as a whole (submission, the CLI's sweep and job
// commands, archives): create, grow, pause, cancel, delete, prune, import,
// retry, supersede, back up.
class SweepAdministration {
 public:
  virtual ~SweepAdministration() = default;

  // Stores the sweep and its jobs (all queued, ordinals in vector order).
  // If a sweep with that name exists: same spec_hash (or one of
  // equivalent_spec_hashes) -> returns it with *created = false and stores
  // nothing; different hash -> AlreadyExists.
  virtual absl::StatusOr<SweepRecord> CreateSweep(const NewSweep& sweep, int64_t now_ms,
                                                  bool* created) = 0;

  // Sets a sweep's state. kCancelled also cancels its queued and running jobs
  // (open attempts stay open until the worker answers the CANCEL directive or
  // the lease is lost); kRunning from kCancelled re-queues its cancelled jobs
  // (running again if their attempt is still open). NotFound if no such sweep.
  virtual absl::Status SetSweepState(const std::string& name, SweepState state,
                                     int64_t now_ms) = 0;

  // Deletes sweep `name` and every row stored for it, in one transaction:
  // its jobs, their options, attempts, episodes, study rows, checkpoints and
  // events, and its view; one event "sweep_deleted" (no sweep id) records
  // the name and the counts. NotFound if no such sweep. FailedPrecondition,
  // deleting nothing, while an attempt of the sweep is open (a worker holds
  // its lease: cancel the sweep and let the trials stop first), or when the
  // sweep's contents differ from `expected` (it changed after the caller
  // archived it). Returns what was deleted.
  virtual absl::StatusOr<SweepContents> DeleteSweep(const std::string& name,
                                                    const SweepContents& expected,
                                                    int64_t now_ms) = 0;

  // What a sweep's rows take (SweepDiskUse) and, for a scope other than
  // kNone, removes that scope's checkpoints in the same transaction (one
  // event "checkpoints_pruned" records what). Checkpoints of jobs not
  // completed (the points their next attempts resume from) are never
  // removed. NotFound if no such sweep.
  virtual absl::StatusOr<SweepDiskUse> PruneCheckpoints(const std::string& name, PruneScope scope,
                                                        int64_t now_ms) = 0;

  // Grows an existing sweep to `grown` (the union of its spec and a
  // resubmission, sweep::UnionOfSweeps): stores its jobs that the sweep lacks
  // (identity (kind, method, seed, variant); ordinals after the last), and
  // the new canonical spec, hash, description and source. Returns how many
  // jobs were added. NotFound if there is no sweep of that name;
  // FailedPrecondition (nothing changes) if a stored job's options differ
  // from the same job's in `grown` for a key both list (a default changed
  // between the builds: the sweep would mix two computations).
  virtual absl::StatusOr<int> GrowSweep(const NewSweep& grown, int64_t now_ms) = 0;

  // Takes over the completed jobs of a sweep archive, in one transaction.
  // With `create` the sweep is created first (AlreadyExists if a sweep of
  // that name exists with another spec hash; with the same hash it is used
  // as is). Each archived job is matched by (kind, method, seed, variant); a
  // job completed in the archive and not completed (nor running) here gets
  // the archive's attempts appended after its own (renumbered), with their
  // episodes and study rows, and becomes completed as in the archive. Every
  // other job is left alone and counted in the result. A duplicate is thus
  // refused by its key: an episode row never exists twice. NotFound if the
  // sweep does not exist and `create` is null.
  // The jobs come from `jobs`, which hands each to the store's callback in
  // turn (an archive read as a stream: ForEachArchivedJob), so the store
  // holds one archived job at a time; an error `jobs` returns (its own or
  // the callback's) rolls the whole import back.
  virtual absl::StatusOr<ImportResult> ImportJobStream(const std::optional<NewSweep>& create,
                                                       const std::string& sweep_name,
                                                       const ImportedJobProducer& jobs,
                                                       const std::string& source,
                                                       int64_t now_ms) = 0;
  // ImportJobStream of jobs in memory.
  absl::StatusOr<ImportResult> ImportJobs(const std::optional<NewSweep>& create,
                                          const std::string& sweep_name,
                                          const std::vector<ImportedJob>& jobs,
                                          const std::string& source, int64_t now_ms) {
    return ImportJobStream(create, sweep_name, ProduceEach(jobs), source, now_ms);
  }

  // Puts a failed or cancelled job back in the queue with zeroed failure and
  // lost-lease counts. A job of a cancelled sweep runs alone: the sweep
  // becomes running, its other cancelled jobs stay cancelled.
  // FailedPrecondition for a job in another state, or one of a cancelled
  // sweep whose attempt is still open; NotFound if no such job.
  virtual absl::Status RetryJob(int64_t job_id, int64_t now_ms) = 0;

  // Replaces completed trial `job_id`'s result by completed trial
  // `by_job_id`'s (a re-run of the same trial in another sweep; whether the
  // two are the same trial is the caller's to check): a new attempt of
  // `job_id` copies `by_job_id`'s completed attempt (its worker, build,
  // times, episodes and checkpoint), names it in its `origin`, and becomes
  // the job's completed attempt with its success and final cost; the job's
  // earlier attempts stay as they were, and an event records it. Returns the
  // new attempt's number; if the job already counts a copy of that attempt
  // of `by_job_id` (superseded by it before, here or where an imported
  // archive was written: same sweep named, same worker, build and times),
  // nothing changes and that attempt's number is returned. FailedPrecondition unless both are
  // completed trial jobs of different sweeps with the same method and seed;
  // NotFound if either does not exist.
  virtual absl::StatusOr<int> SupersedeJob(int64_t job_id, int64_t by_job_id, int64_t now_ms) = 0;

  // Writes a consistent copy of the database to `path` (which must not
  // exist) while the store stays usable. Returns its size in bytes.
  virtual absl::StatusOr<int64_t> Backup(const std::string& path) = 0;
};

// Reading what is stored (the dashboard, results, the CLI's --db reads).
// Every read sees one committed state.
class StoreReader {
 public:
  virtual ~StoreReader() = default;

  virtual absl::StatusOr<SweepRecord> GetSweep(const std::string& name) = 0;

  // Newest first.
  virtual absl::StatusOr<std::vector<SweepRecord>> ListSweeps() = 0;

  virtual absl::StatusOr<JobRecord> GetJob(int64_t job_id) = 0;

  virtual absl::StatusOr<std::vector<JobRecord>> ListJobs(const JobFilter& filter) = 0;

  virtual absl::StatusOr<std::vector<AttemptRecord>> ListAttempts(int64_t job_id) = 0;

  virtual absl::StatusOr<std::vector<EventRecord>> ListEvents(int64_t job_id) = 0;

  // The checkpoint of attempt `attempt` of the job, or with attempt 0 the
  // latest over all its attempts (highest episode, then highest attempt);
  // nullopt if there is none.
  virtual absl::StatusOr<std::optional<CheckpointRecord>> GetCheckpoint(int64_t job_id,
                                                                        int attempt) = 0;

  virtual absl::StatusOr<std::vector<WorkerRecord>> ListWorkers() = 0;

  // NotFound if never seen.
  virtual absl::StatusOr<WorkerRecord> GetWorker(const std::string& worker_id) = 0;

  // The completed trial jobs of a sweep, in job order, each with its
  // counting attempt, verdict, final evaluation cost, rollout verdict and
  // episode count; `sweep` set, `options` left empty (StoreResultsReader
  // joins them). NotFound if no such sweep.
  virtual absl::StatusOr<std::vector<results::CompletedTrial>> ListTrialResults(
      const std::string& sweep_name) = 0;

  // Calls `sink` with batches of at most `batch_size` rows ordered by job,
  // attempt, episode; stops at the first non-OK status `sink` returns and
  // returns it. Only each job's counting attempt (completed, else latest)
  // unless `all_attempts`. NotFound if no such sweep.
  virtual absl::Status ExportEpisodes(
      const std::string& sweep_name, bool all_attempts, int batch_size,
      const std::function<absl::Status(std::vector<EpisodeRowRecord>)>& sink) = 0;

  // Study rows of the sweep's study jobs, ordered by job and index; only each
  // job's counting attempt unless `all_attempts`. NotFound if no such sweep.
  virtual absl::Status ListStudyRows(const std::string& sweep_name, bool all_attempts,
                                     std::vector<StudyCellRecord>* cells,
                                     std::vector<StudyReferenceRecord>* references) = 0;

  virtual absl::StatusOr<StoreCounts> Counts() = 0;
};

// The whole store, one implementation of the three (SqliteStore); a user
// that needs only one part takes that interface.
class Store : public LeaseStore, public SweepAdministration, public StoreReader {
 public:
  ~Store() override = default;
};

// Opens an existing coordinator database for reading only, behind Store's
// interface (SqliteStore::OpenReadOnly says what it refuses; every write
// returns FailedPrecondition), so that readers such as `results --db`
// include no storage implementation.
absl::StatusOr<std::unique_ptr<Store>> OpenStoreReadOnly(const std::string& path);
// Opens a coordinator database for writing without a coordinator (`results
// import FILE --db DB`): creates it when missing, takes its lock as a
// coordinator does, so it is refused (FailedPrecondition naming the holder)
// while a coordinator or another writer has the file; otherwise
// SqliteStore::Open's refusals.
absl::StatusOr<std::unique_ptr<Store>> OpenStoreForWriting(const std::string& path);

}  // namespace totalgrad::storage

#endif  // TOTALGRAD_SERVER_STORAGE_STORE_H_
