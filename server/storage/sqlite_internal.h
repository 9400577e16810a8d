// Row helpers shared by the files of SqliteStore (sqlite_store.h; one file
// per job: sqlite_store.cc opens and guards the file, sqlite_sweeps.cc
// sweeps, jobs and workers, sqlite_attempts.cc attempts and their results,
// sqlite_results.cc the results reads, sqlite_import.cc archives and grown
// sweeps, sqlite_write_queue.cc the group commit of writes). Internal to
// server/storage.
//
// Threading: as internal::Db; every function runs inside the caller's
// transaction on the connection it is given.
#ifndef TOTALGRAD_SERVER_STORAGE_SQLITE_INTERNAL_H_
#define TOTALGRAD_SERVER_STORAGE_SQLITE_INTERNAL_H_

#include <cstdint>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "absl/strings/string_view.h"
#include "server/storage/sqlite_db.h"
#include "server/storage/job_kinds.h"
#include "server/storage/store.h"

namespace totalgrad::storage::internal {

// Milliseconds of the steady clock (for intervals within this process).
int64_t SteadyMs();
// Storage failures (as opposed to a refusal of the request itself).
bool IsDatabaseFailure(const absl::Status& status);

// Doubles as JSON arrays: round-trip precision; NaN and +-Inf as null.
std::string DoublesToJson(const std::vector<double>& values);
std::vector<double> DoublesFromJson(const std::string& text);
// Options as the jobs.options_json column holds them: [[key, value], ...].
std::string OptionsToJson(const OptionPairs& options);
OptionPairs OptionsFromJson(const std::string& text);

// A trial job's options from its sweep's shared list (sweeps.
// trial_options_json): the shared pairs in their order, each key the job
// has in job_options (JobOptionPairs) with the job's value.
OptionPairs WithJobValues(const OptionPairs& shared, const OptionPairs& job_values);

// The last shared list parsed, so that reading many jobs of a sweep parses
// it once. Keyed by the list's text, never by a sweep id (a deleted sweep's
// id can be taken again).
struct SharedOptionsCache {
  std::string text;
  OptionPairs options;
};
// A job's whole option list from its row: `stored` (jobs.options_json) as
// it is, or for a trial job that stores '' (schema 10) WithJobValues of its
// sweep's `shared` list and its own method, seed and variant.
OptionPairs StoredJobOptions(const std::string& stored, JobKind kind, const std::string& method,
                             const std::string& seed, const std::string& variant,
                             const std::optional<std::string>& shared, SharedOptionsCache* cache);
// The same in SQL, for the job row aliased `j` (the view job_option_lists,
// the per-sweep views' protocol columns): WithJobValues of the sweep's list
// and the job's job_options rows. QueuedJobInserter stores '' only where
// both give back the job's list.
const char* JobOptionsJsonSql();

// The queries behind SqliteStore::ListClaimCandidates: the running sweeps
// with their running counts (no parameter), then one sweep's first queued
// jobs (parameters: sweep id, limit). Their plans read only the rows they
// return, whatever the queue's length (storage_test checks the plans).
const char* ClaimSweepsSql();
const char* ClaimJobsSql();

// The queries an import (ImportJobStream) and a grown sweep (GrowSweep) run:
// a sweep's jobs with their identities, read once (parameter: sweep id),
// then per job by its id: its state, attempts and episodes expected; its
// stored options (options_json, seed, the sweep's trial_options_json). No
// plan scans a sweep per job (storage_test checks the plans).
const char* SweepJobIdsSql();
const char* ImportedJobStateSql();
const char* StoredJobOptionsSql();

// One row of `episodes`: the key, the episode's record (its columns from
// learner::EpisodeFields(), sqlite_records.h), details_json and
// reported_ms; a stored (job, attempt, episode) is kept (ON CONFLICT DO
// NOTHING). BindEpisode binds every parameter of that statement.
std::string EpisodeInsertSql();
void BindEpisode(Statement& insert, const LeaseKey& key, const Episode& episode,
                 int64_t reported_ms);

// GetJobStatus on `db` (the reader, or the writer inside a transaction).
absl::StatusOr<JobStatus> ReadJobStatus(Db& db, int64_t job_id);

// Inserts or refreshes a worker's row (TouchWorker's body).
absl::Status UpsertWorker(Db& db, const WorkerIdentity& worker, int64_t now_ms);

// Appends to the event log (sweep_id, job_id 0: none).
absl::Status AddEvent(Db& db, int64_t ms, int64_t sweep_id, int64_t job_id, int attempt,
                      absl::string_view kind, absl::string_view message);
// Reads an int from a one-row query with one parameter (0 without a row).
absl::StatusOr<int64_t> QueryInt(Db& db, absl::string_view sql, int64_t param);

// "SELECT <a sweep's columns> FROM sweeps s" (append WHERE / ORDER BY);
// ReadSweepRow reads its rows and adds the job counts.
const std::string& SweepSelectSql();
absl::StatusOr<SweepRecord> ReadSweepRow(Db& db, const Statement& row);
absl::StatusOr<SweepRecord> LoadSweep(Db& db, const std::string& name);

// "SELECT <a job's values> FROM jobs j JOIN sweeps s ON s.id = j.sweep_id"
// (append WHERE / ORDER BY); ReadJobRow reads its rows (`cache`: for many
// rows of one query; may be null).
const std::string& JobSelectSql();
JobRecord ReadJobRow(const Statement& row, SharedOptionsCache* cache = nullptr);
absl::StatusOr<JobRecord> LoadJob(Db& db, int64_t job_id);

struct OpenAttempt {
  JobKind kind = JobKind::kTrial;
  AttemptState state = AttemptState::kRunning;
  std::string worker_id;
  int job_attempts = 0;
  int episodes_expected = 0;
  int64_t sweep_id = 0;
  int64_t lease_expires_ms = 0;
};

// Loads the attempt and the job's latest attempt number. NotFound if the job
// does not exist; Aborted if the attempt does not exist.
absl::StatusOr<OpenAttempt> LoadAttempt(Db& db, const LeaseKey& key);
// The fence: the attempt must be open, the job's latest, and owned by `worker_id`.
absl::Status CheckOpen(const LeaseKey& key, const OpenAttempt& attempt,
                       const std::string& worker_id);

// Stores `results` for the attempt (rows already stored are kept:
// ON CONFLICT DO NOTHING). InvalidArgument, before anything is written: rows
// of a table the attempt's kind does not own (job_kinds.h), an episode
// outside [0, episodes_expected), a negative study row index.
absl::Status InsertResults(Db& db, const LeaseKey& key, const OpenAttempt& attempt,
                           const JobResults& results, int64_t now_ms);
// Rows stored for the attempt in each of its kind's tables.
absl::StatusOr<ResultTotals> CountResults(Db& db, const LeaseKey& key, const JobKindInfo& kind);
// The one missing-rows query: the indexes in 0..total-1 that `table` does
// not hold for the attempt.
absl::StatusOr<std::vector<int>> MissingRows(Db& db, const LeaseKey& key,
                                             const ResultTable& table, int total);
// Keeps `checkpoint` for the attempt unless it holds one of a later episode.
absl::Status UpsertCheckpoint(Db& db, const LeaseKey& key, const OpenAttempt& attempt,
                              const Checkpoint& checkpoint, int64_t now_ms);
// CreateSweep inside the caller's transaction: *created tells whether it
// was inserted (false: a sweep of that name and hash existed).
absl::Status InsertSweep(Db& db, const NewSweep& sweep, int64_t now_ms, bool* created);
// Inserts queued jobs of sweep `sweep_id`, one per Insert call, with
// ordinals first_ordinal, first_ordinal + 1, ..., each with its job_options
// rows (sweep creation and growth), through one prepared statement; the
// caller holds the write transaction and `db` outlives the inserter. A
// trial job's options are stored once per sweep where they can be
// (schema version 10, JobOptionsJsonSql).
class QueuedJobInserter {
 public:
  static absl::StatusOr<QueuedJobInserter> Prepare(Db& db, int64_t sweep_id,
                                                   int64_t first_ordinal);
  absl::Status Insert(const NewJob& job);
  int64_t inserted() const { return inserted_; }

 private:
  QueuedJobInserter(Db& db, Statement insert, int64_t sweep_id, int64_t first_ordinal,
                    std::optional<OptionPairs> shared_options)
      : db_(&db), insert_(std::move(insert)), sweep_id_(sweep_id), next_ordinal_(first_ordinal),
        shared_options_(std::move(shared_options)) {}
  // The options_json column for `job`: '' when its options are the sweep's
  // shared ones with its own values (set from the first trial job if the
  // sweep has none yet), else the whole list.
  absl::StatusOr<std::string> StoredOptions(const NewJob& job);
  Db* db_;
  Statement insert_;
  int64_t sweep_id_;
  int64_t next_ordinal_;
  std::optional<OptionPairs> shared_options_;  // sweeps.trial_options_json, once set
  int64_t inserted_ = 0;
};

}  // namespace totalgrad::storage::internal

#endif  // TOTALGRAD_SERVER_STORAGE_SQLITE_INTERNAL_H_
