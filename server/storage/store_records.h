// The records the coordinator's Store (store.h) reads and writes: sweeps,
// jobs, attempts, episodes, checkpoints, study rows, workers, events, and
// what imports, exports and pruning report. Plain data; the schema that
// holds them is docs/results_schema.md.
#ifndef TOTALGRAD_SERVER_STORAGE_STORE_RECORDS_H_
#define TOTALGRAD_SERVER_STORAGE_STORE_RECORDS_H_

#include <cmath>
#include <cstdint>
#include <functional>
#include <limits>
#include <memory>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "absl/status/status.h"
#include "absl/strings/string_view.h"
#include "core/common/option_pairs.h"
#include "core/learner/episode_record.h"
#include "core/study/study.h"
#include "results/completed_trial.h"
#include "runtime/job_kind.h"

namespace totalgrad::storage {

enum class SweepState { kRunning, kPaused, kCancelled };

// What one sweep holds, counted as a sweep archive counts it
// (Store::DeleteSweep's guard: delete only what was archived).
struct SweepContents {
  int64_t jobs = 0;
  int64_t attempts = 0;
  int64_t episodes = 0;    // every attempt's
  int64_t study_rows = 0;  // cells and references, every attempt's
  bool operator==(const SweepContents&) const = default;
};
enum class JobState { kQueued, kRunning, kCompleted, kFailed, kCancelled };
enum class AttemptState { kRunning, kCompleted, kFailed, kLeaseLost, kReleased, kCancelled };
// What a job runs and reports (runtime/job_kind.h, the one
// definition); what differs between kinds is data in job_kinds.h.
using ::totalgrad::JobKind;

// Names as stored in the database ("running", "lease_lost", ...).
absl::string_view ToString(SweepState state);
absl::string_view ToString(JobState state);
absl::string_view ToString(AttemptState state);
absl::string_view ToString(JobKind kind);
std::optional<SweepState> ParseSweepState(absl::string_view text);
std::optional<JobState> ParseJobState(absl::string_view text);
std::optional<AttemptState> ParseAttemptState(absl::string_view text);


inline constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

struct LeaseKey {
  int64_t job_id = 0;
  int attempt = 0;  // the lease's epoch
  friend bool operator==(const LeaseKey&, const LeaseKey&) = default;
};

struct WorkerIdentity {
  std::string worker_id;
  std::string host;
  std::string build;
  int slots = 1;
  // The worker can run study jobs (not stored: sent with every AcquireLease).
  bool study_jobs = false;
  // Not stored either; the scheduler uses them to refuse a second live
  // process with the same worker_id (see Scheduler::TryAcquire). `instance`
  // is unique per worker process ("" from older workers: not checked);
  // `takes_over` says the process holds its host-local worker-id lock, so an
  // earlier process with this id on this host has exited.
  std::string instance;
  bool takes_over = false;
};

// One finished episode: its record (learner::EpisodeSummary; fields,
// columns and proto fields listed once in learner::EpisodeFields()) and the
// trial's details as the worker sent them (a JSON object, stored verbatim).
// NaN = no value (stored as NULL).
struct Episode : learner::EpisodeSummary {
  std::string details_json;
};

// A trial's state after a finished episode (core/learner/checkpoint.h),
// opaque here: the store keeps the latest one of each attempt.
struct Checkpoint {
  int episode = 0;
  int format_version = 0;
  std::string data;
};

struct CheckpointRecord {
  LeaseKey key;              // the attempt that stored it
  std::string worker_build;  // of that attempt
  Checkpoint checkpoint;
};

// Which checkpoints Store::PruneCheckpoints removes.
enum class PruneScope {
  kNone,       // none: a report of what the sweep's rows take
  kStale,      // completed jobs' checkpoints of attempts other than the counting one: read by nothing
  kCompleted,  // kStale and the counting attempts' own: the final states, so the trials'
               // trajectories (checkpoint format 4) and `job artifacts` with them
};

struct CheckpointUse {
  int count = 0;
  int64_t bytes = 0;  // of the checkpoints' data
};

// What a sweep's rows take: its episode rows (their details text, the part
// that grows with the GP's size) and its checkpoints by what reads them.
struct SweepDiskUse {
  int64_t episodes = 0;
  int64_t episode_details_bytes = 0;
  CheckpointUse completed;   // of completed jobs' counting attempts
  CheckpointUse stale;       // of completed jobs' other attempts
  CheckpointUse unfinished;  // of jobs not completed
  CheckpointUse removed;     // by this call
};

struct NewJob {
  std::string method;
  std::string seed;
  std::string variant;
  OptionPairs options;
  int episodes_expected = 0;  // study jobs: 0
  JobKind kind = JobKind::kTrial;
  std::string payload;        // study jobs: the self-contained study spec (JSON)
};

// Jobs made on demand, one at a time, the same ones in the same order on
// every call (NewSweep::generated_jobs). Implementations are immutable, so
// a store may walk them more than once.
class NewJobGenerator {
 public:
  virtual ~NewJobGenerator() = default;
  virtual int64_t size() const = 0;
  virtual int64_t episodes_expected() const = 0;  // summed over the jobs
  // Calls `visit` on each job in order; returns the first error (`visit`'s,
  // or one from making a job) and visits nothing after it.
  virtual absl::Status ForEach(const std::function<absl::Status(const NewJob&)>& visit) const = 0;
};

// One cell of a gradient study as stored: the core record itself
// (study::CellResult; its fields, columns and proto fields are listed once,
// in study::CellFields()) and the row's key: `index` is the cell's position
// in the study's result, the row's key within an attempt. NaN: no value
// (NULL).
struct StudyCell : study::CellResult {
  int index = 0;
};

// The reference gradient of one horizon as stored (study::ReferenceGradient,
// fields in study::ReferenceFields()), keyed by its position in the study's
// reference list.
struct StudyReference : study::ReferenceGradient {
  int index = 0;
};

struct StudyRows {
  std::vector<StudyCell> cells;
  std::vector<StudyReference> references;
  bool empty() const { return cells.empty() && references.empty(); }
  size_t size() const { return cells.size() + references.size(); }
};

// Rows a job reports, one member per result table (job_kinds.h says which
// kind owns which table; rows of a table the job's kind does not own are
// refused). Each row carries its key within the attempt (its index).
// (The `= {}` lets a bundle of one table's rows be written `{episodes}`
// without -Wmissing-field-initializers.)
struct JobResults {
  std::vector<Episode> episodes = {};  // table episodes (trials)
  StudyRows study = {};                // tables study_cells, study_references (studies)
  bool empty() const { return episodes.empty() && study.empty(); }
};

// A number of rows per result table: what a completion reports its job
// produced, or what is stored for an attempt (Store::StoreResults).
struct ResultTotals {
  int episodes = 0;
  int study_cells = 0;
  int study_references = 0;
  bool operator==(const ResultTotals&) const = default;
};

// How a worker completes an attempt (Scheduler::Complete): rows not yet
// acknowledged, stored first; how many rows of each of its kind's tables the
// job produced (the completion check, job_kinds.h); the verdict, for kinds
// that report one (trials: success and the final evaluation cost); and the
// final checkpoint, for kinds that keep them.
struct JobCompletion {
  JobResults results;
  ResultTotals totals;
  bool success = false;
  double final_eval_cost = kNaN;
  std::optional<Checkpoint> checkpoint;
};

// Stored study rows with their job's coordinates (ListStudyRows).
struct StudyCellRecord {
  int64_t job_id = 0;
  int attempt = 0;
  std::string study;  // the study entry's name (the job's variant)
  bool final_attempt = false;
  StudyCell cell;
};
struct StudyReferenceRecord {
  int64_t job_id = 0;
  int attempt = 0;
  std::string study;
  bool final_attempt = false;
  StudyReference reference;
};

struct NewSweep {
  std::string name;
  std::string description;
  std::string canonical_spec;
  std::string spec_hash;
  // Hashes an older build gave this same spec (sweep::LegacySpecHash): a
  // stored sweep with one of them is this sweep, not a different one.
  std::vector<std::string> equivalent_spec_hashes;
  std::string source_name;
  std::string source_text;
  std::string coordinator_build;
  int max_attempts = 3;
  int max_lost_leases = 20;
  int max_concurrent = 0;
  // The sweep's jobs are `jobs`, then those of `generated_jobs` when set (in
  // ordinal order): a coordinator's submission generates its jobs from the
  // spec while the store inserts them instead of holding them all (issue 28
  // item 3: 100,000 jobs as a vector took about 480 MB).
  std::vector<NewJob> jobs;
  std::shared_ptr<const NewJobGenerator> generated_jobs;
  // When the sweep was first submitted (Unix ms); 0: now. An imported sweep
  // keeps its archive's time.
  int64_t created_ms = 0;

  int64_t job_count() const;
  int64_t episodes_expected() const;  // summed over every job
  // Calls `visit` on every job in ordinal order; the first error, `visit`'s
  // or the generator's, stops it and is returned.
  absl::Status ForEachJob(const std::function<absl::Status(const NewJob&)>& visit) const;
};

struct SweepRecord {
  int64_t id = 0;
  std::string name;
  std::string description;
  SweepState state = SweepState::kRunning;
  std::string canonical_spec;
  std::string spec_hash;
  std::string source_name;
  std::string coordinator_build;
  int64_t created_ms = 0;
  int max_attempts = 0;
  int max_lost_leases = 0;
  int max_concurrent = 0;
  int jobs_total = 0;
  int jobs_queued = 0;
  int jobs_running = 0;
  int jobs_completed = 0;
  int jobs_failed = 0;
  int jobs_cancelled = 0;
  int64_t episodes_stored = 0;    // for each job's counting attempt
  int64_t episodes_expected = 0;  // sum over jobs
  bool finished() const { return jobs_queued == 0 && jobs_running == 0; }
};

// What a job's lease decisions read (Store::GetJobStatus): a subset of
// JobRecord's fields, the same values.
struct JobStatus {
  int64_t id = 0;
  JobKind kind = JobKind::kTrial;
  JobState state = JobState::kQueued;
  int failures = 0;
  int lost_leases = 0;
  int max_attempts = 0;      // the sweep's
  int max_lost_leases = 0;   // the sweep's
};

struct JobRecord {
  int64_t id = 0;
  JobKind kind = JobKind::kTrial;
  std::string payload;  // study jobs: the study spec
  int64_t sweep_id = 0;
  std::string sweep_name;
  SweepState sweep_state = SweepState::kRunning;
  int ordinal = 0;
  std::string method;
  std::string seed;
  std::string variant;
  OptionPairs options;
  JobState state = JobState::kQueued;
  int attempts = 0;  // leases granted; the latest attempt's number
  int failures = 0;
  int lost_leases = 0;
  int max_attempts = 0;     // of its sweep
  int max_lost_leases = 0;  // of its sweep
  int episodes_expected = 0;
  int episodes_stored = 0;  // of the latest attempt
  std::string worker_id;    // of the open attempt, if running
  std::string last_error;
  int completed_attempt = 0;  // 0 unless completed
  bool success = false;
  double final_eval_cost = kNaN;
  // Of the completed attempt's last episode (learner::EpisodeSummary::
  // held_fraction): the rollout verdict's fraction held; NaN when the job is
  // not completed or its trial classified no rollouts.
  double held_fraction = kNaN;
};

struct AttemptRecord {
  LeaseKey key;
  AttemptState state = AttemptState::kRunning;
  std::string worker_id;
  std::string worker_host;
  std::string worker_build;
  int64_t started_ms = 0;
  int64_t ended_ms = 0;  // 0 while running
  int64_t lease_expires_ms = 0;
  std::string error;
  int episodes_stored = 0;
  int checkpoint_episode = -1;  // of its stored checkpoint; -1: none
  // Where an attempt that no worker ran here came from: `job supersede`
  // names the job, attempt and sweep it copied ("" for the others).
  std::string origin;
};

struct EventRecord {
  int64_t ms = 0;
  int64_t job_id = 0;  // 0: sweep-level event
  int attempt = 0;
  std::string kind;
  std::string message;
};

struct WorkerRecord {
  WorkerIdentity identity;
  int64_t first_seen_ms = 0;
  int64_t last_seen_ms = 0;
  bool draining = false;
  int running = 0;  // open attempts
};

struct EpisodeRowRecord {
  int64_t job_id = 0;
  int attempt = 0;
  std::string method;
  std::string seed;
  std::string variant;
  Episode episode;
  int64_t reported_ms = 0;
  bool final_attempt = false;
};

// A queued job that could be leased now (its sweep is below its concurrency
// limit: Store::ListClaimCandidates leaves out sweeps at theirs).
struct ClaimCandidate {
  int64_t job_id = 0;
  JobKind kind = JobKind::kTrial;
  int attempts = 0;
  int64_t sweep_id = 0;
};

// A lease request as the store decides it in one transaction (ClaimJob).
struct ClaimRequest {
  WorkerIdentity worker;
  // Which candidates the worker can run (the scheduler's rule); empty: all.
  std::function<bool(const ClaimCandidate&)> suits;
  // Candidates read first; all `scan_limit` only when none of those suits.
  int first_scan = 8;
  int scan_limit = 256;
  int64_t now_ms = 0;
  int64_t lease_expires_ms = 0;
};

struct JobFilter {
  std::string sweep_name;        // empty: all
  std::vector<JobState> states;  // empty: all
  int64_t after_job_id = 0;
  int limit = 1000;
};

struct StoreCounts {
  int sweeps = 0;
  int jobs_queued = 0;
  int jobs_running = 0;
};

// How an attempt ends (EndAttempt).
struct AttemptEnd {
  LeaseKey key;
  std::string worker_id;         // must own the attempt
  AttemptState attempt_state = AttemptState::kCompleted;  // not kRunning
  JobState job_state = JobState::kCompleted;  // the job's next state
  JobResults results;             // stored first, in the same transaction
  std::string error;              // kept as the attempt's and job's error
  int failures_delta = 0;         // added to the job's failure count
  int lost_leases_delta = 0;      // added to the job's lost-lease count
  // Completion only (checked whatever job_state says): how many rows of each
  // of the kind's result tables the job produced, checked by the kind's
  // completion rule (job_kinds.h: a trial's episodes must be its
  // episodes_expected; a study's totals are the worker's, >= 1). All rows
  // 0..total-1 of each table must then be stored. The job's
  // completed_attempt, success and final_eval_cost are set (as given) only
  // when job_state is kCompleted.
  ResultTotals totals;
  bool success = false;
  double final_eval_cost = kNaN;
  // Stored with the rows (as StoreCheckpoint), e.g. the final state.
  std::optional<Checkpoint> checkpoint;
  int64_t now_ms = 0;
  // Decides the fields above from the job as it is inside the end's own
  // transaction (its state, failure and lost-lease counts, the sweep's
  // budgets), so that a decision is never taken on a state that changed
  // before it was written (a cancel, another end). May change
  // attempt_state, job_state, the deltas and error; an error refuses the end
  // (nothing changes). Empty: the fields are taken as they are.
  std::function<absl::Status(const JobStatus& job, AttemptEnd* end)> decide;
  // The lease expiry's condition (kLeaseLost), 0 for none: end the attempt
  // only if its lease still expires before this time (lease clock, ms). The
  // expiry reads expired leases outside the write transaction, and a
  // heartbeat may extend one before the end is written: then nothing
  // changes and the outcome is kLeaseRenewed.
  int64_t only_if_lease_expires_before_ms = 0;
};

// One attempt of a job as a sweep archive carries it (`results export` on
// one coordinator, `results import` on another).
struct ImportedAttempt {
  int attempt = 0;  // its number where it ran (renumbered where it lands)
  AttemptState state = AttemptState::kCompleted;
  std::string worker_id;
  std::string worker_host;
  std::string worker_build;
  int64_t started_ms = 0;
  int64_t ended_ms = 0;
  std::string error;
  std::string origin;  // AttemptRecord::origin
  std::vector<std::pair<Episode, int64_t>> episodes;  // with the time it was reported
  StudyRows study;
  // Its checkpoint, when the archive kept it (the completed attempt's final
  // state: the trial's final policy and GP data, `job artifacts`).
  std::optional<Checkpoint> checkpoint;
};

// A job of a sweep archive, identified by (kind, method, seed, variant).
struct ImportedJob {
  // The job as the archive has it (storage::JobFields()). The import takes
  // its identity (kind, method, seed, variant), state, failures,
  // lost_leases, last_error, success and final_eval_cost; the rest (ids,
  // counts, worker, options) is the exporting coordinator's and is ignored.
  JobRecord record;
  int completed_attempt = 0;  // archive numbering; 0 unless completed
  std::vector<ImportedAttempt> attempts;
  // A trial's options as its completed attempt ran them, every key of this
  // build's option table (the reader of the archive fills the keys the
  // archive's build did not have with the value they had before they
  // existed: learner::TrialOptionsFromStoredPairs). When they differ from
  // what this sweep gives the job here, the import stores them as the job's
  // own list, so that the stored options say what ran; unset: the job keeps
  // this sweep's.
  std::optional<OptionPairs> options_as_run;
};

// Hands each job of an import to `each`, in order, and returns the first
// error, its own or `each`'s (Store::ImportJobStream).
using ImportedJobProducer =
    std::function<absl::Status(const std::function<absl::Status(const ImportedJob&)>& each)>;

// A producer of `jobs` (which must outlive it).
inline ImportedJobProducer ProduceEach(const std::vector<ImportedJob>& jobs) {
  return [&jobs](const std::function<absl::Status(const ImportedJob&)>& each) {
    for (const ImportedJob& job : jobs) {
      if (absl::Status status = each(job); !status.ok()) return status;
    }
    return absl::OkStatus();
  };
}

struct ImportResult {
  bool sweep_created = false;
  int jobs_imported = 0;           // completed in the archive, not yet here: taken over
  int jobs_already_complete = 0;   // completed here: kept, the archive's copy ignored
  int jobs_not_completed = 0;      // not completed in the archive: nothing to take
  int jobs_running_here = 0;       // running here: left alone
  int jobs_unknown = 0;            // not a job of the sweep here
  int64_t episodes_imported = 0;
  int64_t study_rows_imported = 0;
  int checkpoints_imported = 0;
  // Jobs taken over whose options_as_run differ from this sweep's and are
  // stored as their own, and the keys that differ (sorted).
  int jobs_keeping_options = 0;
  std::vector<std::string> options_kept;
};

enum class EndOutcome {
  kApplied,
  // The attempt had already ended the same way; nothing changed.
  kAlreadyEnded,
  // only_if_lease_expires_before_ms: a heartbeat extended the lease since
  // it was found expired; nothing changed.
  kLeaseRenewed,
};

}  // namespace totalgrad::storage

#endif  // TOTALGRAD_SERVER_STORAGE_STORE_RECORDS_H_
