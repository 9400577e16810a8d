// SqliteStore: attempts, leases, their results and checkpoints (sqlite_store.h).
#include <algorithm>
#include <optional>
#include <utility>
#include <vector>

#include "absl/strings/str_cat.h"
#include "absl/strings/str_join.h"
#include "runtime/status_macros.h"
#include "server/storage/sqlite_internal.h"
#include "server/storage/sqlite_schema.h"
#include "server/storage/sqlite_store.h"

namespace totalgrad::storage {

using internal::Db;
using internal::Statement;
using namespace internal;  // the row helpers of sqlite_internal.h

namespace {

// Queued jobs of running sweeps below their concurrency limit, oldest sweep
// first then ordinal; at most `limit` (ListClaimCandidates' contract).
absl::StatusOr<std::vector<ClaimCandidate>> ReadClaimCandidates(Db& db, int limit) {
  struct RunningSweep {
    int64_t id;
    int max_concurrent;
    int running;
  };
  std::vector<RunningSweep> sweeps;
  {
    ASSIGN_OR_RETURN(Statement query, Statement::Prepare(db, ClaimSweepsSql()));
    while (true) {
      ASSIGN_OR_RETURN(bool row, query.Step());
      if (!row) break;
      sweeps.push_back({query.ColumnInt(0), static_cast<int>(query.ColumnInt(1)),
                        static_cast<int>(query.ColumnInt(2))});
    }
  }
  ASSIGN_OR_RETURN(Statement jobs, Statement::Prepare(db, ClaimJobsSql()));
  std::vector<ClaimCandidate> candidates;
  for (const RunningSweep& sweep : sweeps) {
    if (static_cast<int>(candidates.size()) >= limit) break;
    // A sweep at its max_concurrent offers nothing: its queued jobs would
    // only fill the scan and hide the next sweep's.
    if (sweep.max_concurrent > 0 && sweep.running >= sweep.max_concurrent) continue;
    jobs.Reset();
    jobs.Bind(1, sweep.id);
    jobs.Bind(2, limit - static_cast<int>(candidates.size()));
    while (true) {
      ASSIGN_OR_RETURN(bool row, jobs.Step());
      if (!row) break;
      ClaimCandidate c;
      c.job_id = jobs.ColumnInt(0);
      c.attempts = static_cast<int>(jobs.ColumnInt(1));
      c.kind = ParseJobKind(jobs.ColumnText(2)).value_or(JobKind::kTrial);
      c.sweep_id = sweep.id;
      candidates.push_back(c);
    }
  }
  return candidates;
}

// StartAttempt's body: a compare-and-set on the job's state and attempts.
absl::Status OpenAttemptRow(Db& db, const LeaseKey& key, const WorkerIdentity& worker,
                            int64_t now_ms, int64_t lease_expires_ms) {
  ASSIGN_OR_RETURN(Statement update, Statement::Prepare(db, R"sql(
UPDATE jobs SET state = 'running', attempts = ?
WHERE id = ? AND state = 'queued' AND attempts = ?)sql"));
  update.Bind(1, key.attempt).Bind(2, key.job_id).Bind(3, key.attempt - 1);
  RETURN_IF_ERROR(update.Run());
  if (db.Changes() != 1) {
    return absl::FailedPreconditionError(
        absl::StrCat("job ", key.job_id, " is not queued at attempt ", key.attempt - 1));
  }
  ASSIGN_OR_RETURN(Statement insert, Statement::Prepare(db, R"sql(
INSERT INTO attempts(job_id, attempt, state, worker_id, worker_host, worker_build, started_ms,
                     lease_expires_ms)
VALUES(?, ?, 'running', ?, ?, ?, ?, ?))sql"));
  insert.Bind(1, key.job_id).Bind(2, key.attempt).Bind(3, worker.worker_id);
  insert.Bind(4, worker.host).Bind(5, worker.build).Bind(6, now_ms).Bind(7, lease_expires_ms);
  RETURN_IF_ERROR(insert.Run());
  ASSIGN_OR_RETURN(int64_t sweep_id,
                   QueryInt(db, "SELECT sweep_id FROM jobs WHERE id = ?", key.job_id));
  return AddEvent(db, now_ms, sweep_id, key.job_id, key.attempt, "lease_granted",
                  absl::StrCat("worker ", worker.worker_id));
}

}  // namespace

absl::Status SqliteStore::StartAttempt(const LeaseKey& key, const WorkerIdentity& worker,
                                       int64_t now_ms, int64_t lease_expires_ms) {
  return InWriteTransaction([&](Db& db) -> absl::Status {
    return OpenAttemptRow(db, key, worker, now_ms, lease_expires_ms);
  });
}

absl::StatusOr<std::vector<ClaimCandidate>> SqliteStore::ListClaimCandidates(int limit) {
  absl::MutexLock lock(&read_mutex_);
  return ReadClaimCandidates(reader_, limit);
}

absl::StatusOr<std::optional<LeaseKey>> SqliteStore::ClaimJob(const ClaimRequest& request) {
  std::optional<LeaseKey> claimed;
  const absl::Status status = InWriteTransaction([&](Db& db) -> absl::Status {
    RETURN_IF_ERROR(UpsertWorker(db, request.worker, request.now_ms));
    const auto suits = [&](const ClaimCandidate& candidate) {
      return !request.suits || request.suits(candidate);
    };
    ASSIGN_OR_RETURN(std::vector<ClaimCandidate> candidates,
                     ReadClaimCandidates(db, request.first_scan));
    if (static_cast<int>(candidates.size()) == request.first_scan &&
        request.first_scan < request.scan_limit &&
        std::none_of(candidates.begin(), candidates.end(), suits)) {
      ASSIGN_OR_RETURN(candidates, ReadClaimCandidates(db, request.scan_limit));
    }
    const auto first = std::find_if(candidates.begin(), candidates.end(), suits);
    if (first == candidates.end()) return absl::OkStatus();
    const LeaseKey key{first->job_id, first->attempts + 1};
    RETURN_IF_ERROR(OpenAttemptRow(db, key, request.worker, request.now_ms,
                                   request.lease_expires_ms));
    claimed = key;
    return absl::OkStatus();
  });
  if (!status.ok()) return status;
  return claimed;
}

absl::StatusOr<ResultTotals> SqliteStore::StoreResults(const LeaseKey& key,
                                                      const std::string& worker_id,
                                                      const JobResults& results, int64_t now_ms,
                                                      std::optional<int64_t> lease_expires_ms) {
  ResultTotals stored;
  const absl::Status status = InWriteTransaction([&](Db& db) -> absl::Status {
    ASSIGN_OR_RETURN(OpenAttempt attempt, LoadAttempt(db, key));
    RETURN_IF_ERROR(CheckOpen(key, attempt, worker_id));
    RETURN_IF_ERROR(InsertResults(db, key, attempt, results, now_ms));
    if (lease_expires_ms.has_value()) {
      ASSIGN_OR_RETURN(Statement extend,
                       Statement::Prepare(db, "UPDATE attempts SET lease_expires_ms = ? "
                                              "WHERE job_id = ? AND attempt = ?"));
      extend.Bind(1, *lease_expires_ms).Bind(2, key.job_id).Bind(3, key.attempt);
      RETURN_IF_ERROR(extend.Run());
    }
    ASSIGN_OR_RETURN(stored, CountResults(db, key, KindInfo(attempt.kind)));
    return absl::OkStatus();
  });
  if (!status.ok()) return status;
  return stored;
}

absl::Status SqliteStore::StoreCheckpoint(const LeaseKey& key, const std::string& worker_id,
                                          const Checkpoint& checkpoint, int64_t now_ms) {
  return InWriteTransaction([&](Db& db) -> absl::Status {
    ASSIGN_OR_RETURN(OpenAttempt attempt, LoadAttempt(db, key));
    RETURN_IF_ERROR(CheckOpen(key, attempt, worker_id));
    return UpsertCheckpoint(db, key, attempt, checkpoint, now_ms);
  });
}

namespace {

// EndAttempt's body once the end is decided, inside its transaction.
absl::Status EndDecided(Db& db, const AttemptEnd& end, const OpenAttempt& attempt,
                        EndOutcome* outcome) {
  const LeaseKey& key = end.key;
  if (attempt.state == end.attempt_state && attempt.worker_id == end.worker_id) {
    *outcome = EndOutcome::kAlreadyEnded;  // a repeated call: nothing to do
    return absl::OkStatus();
  }
  if (end.only_if_lease_expires_before_ms > 0 && attempt.state == AttemptState::kRunning &&
      attempt.lease_expires_ms >= end.only_if_lease_expires_before_ms) {
    *outcome = EndOutcome::kLeaseRenewed;
    return absl::OkStatus();
  }
  RETURN_IF_ERROR(CheckOpen(key, attempt, end.worker_id));
  RETURN_IF_ERROR(InsertResults(db, key, attempt, end.results, end.now_ms));
  if (end.checkpoint) RETURN_IF_ERROR(UpsertCheckpoint(db, key, attempt, *end.checkpoint, end.now_ms));
  if (end.attempt_state == AttemptState::kCompleted) {
    // The kind's completion check (job_kinds.h): its rule gives each of
    // its tables a total, then one query per table finds what is missing.
    const JobKindInfo& kind = KindInfo(attempt.kind);
    ASSIGN_OR_RETURN(ResultTotals required,
                     RequiredRows(kind, key, attempt.episodes_expected, end.totals));
    for (const ResultTable* table : kind.tables) {
      const int total = required.*table->total;
      ASSIGN_OR_RETURN(std::vector<int> missing, MissingRows(db, key, *table, total));
      if (!missing.empty()) return MissingRowsError(*table, key, missing, total);
    }
  }
  ASSIGN_OR_RETURN(Statement close, Statement::Prepare(db, R"sql(
UPDATE attempts SET state = ?, ended_ms = ?, error = ? WHERE job_id = ? AND attempt = ?)sql"));
  close.Bind(1, ToString(end.attempt_state)).Bind(2, end.now_ms).Bind(3, end.error);
  close.Bind(4, key.job_id).Bind(5, key.attempt);
  RETURN_IF_ERROR(close.Run());
  // The job's result fields only when the job completes (an attempt that
  // completes after a cancel leaves the job cancelled, without a result).
  const bool completed = end.job_state == JobState::kCompleted;
  ASSIGN_OR_RETURN(Statement job, Statement::Prepare(db, R"sql(
UPDATE jobs SET state = ?, failures = failures + ?, lost_leases = lost_leases + ?,
     last_error = CASE WHEN ? = '' THEN last_error ELSE ? END,
     completed_attempt = CASE WHEN ? THEN ? ELSE completed_attempt END,
     success = CASE WHEN ? THEN ? ELSE success END,
     final_eval_cost = CASE WHEN ? THEN ? ELSE final_eval_cost END
WHERE id = ?)sql"));
  job.Bind(1, ToString(end.job_state)).Bind(2, end.failures_delta);
  job.Bind(3, end.lost_leases_delta).Bind(4, end.error).Bind(5, end.error);
  job.Bind(6, completed ? 1 : 0).Bind(7, key.attempt);
  job.Bind(8, completed ? 1 : 0).Bind(9, end.success ? 1 : 0);
  job.Bind(10, completed ? 1 : 0).Bind(11, end.final_eval_cost);
  job.Bind(12, key.job_id);
  RETURN_IF_ERROR(job.Run());
  std::string message = absl::StrCat("worker ", end.worker_id, "; job ", ToString(end.job_state));
  if (!end.error.empty()) absl::StrAppend(&message, ": ", end.error.substr(0, 2000));
  return AddEvent(db, end.now_ms, attempt.sweep_id, key.job_id, key.attempt,
                  ToString(end.attempt_state), message);
}

}  // namespace

absl::StatusOr<EndOutcome> SqliteStore::EndAttempt(const AttemptEnd& end) {
  if (end.attempt_state == AttemptState::kRunning) {
    return absl::InvalidArgumentError("EndAttempt needs a final attempt state, not running");
  }
  EndOutcome outcome = EndOutcome::kApplied;
  const absl::Status status = InWriteTransaction([&](Db& db) -> absl::Status {
    const LeaseKey& key = end.key;
    ASSIGN_OR_RETURN(OpenAttempt attempt, LoadAttempt(db, key));
    if (end.decide) {
      ASSIGN_OR_RETURN(JobStatus job, ReadJobStatus(db, key.job_id));
      AttemptEnd decided = end;
      decided.decide = nullptr;
      RETURN_IF_ERROR(end.decide(job, &decided));
      if (decided.attempt_state == AttemptState::kRunning) {
        return absl::InvalidArgumentError("an attempt cannot end as running");
      }
      return EndDecided(db, decided, attempt, &outcome);
    }
    return EndDecided(db, end, attempt, &outcome);
  });
  if (!status.ok()) return status;
  return outcome;
}




absl::StatusOr<int> SqliteStore::ExtendOpenLeases(int64_t lease_expires_ms, int64_t now_ms,
                                                   const std::string& reason) {
  int changed = 0;
  const absl::Status status = InWriteTransaction([&](Db& db) -> absl::Status {
    ASSIGN_OR_RETURN(Statement update,
                     Statement::Prepare(db, "UPDATE attempts SET lease_expires_ms = ? "
                                            "WHERE state = 'running' AND lease_expires_ms < ?"));
    update.Bind(1, lease_expires_ms).Bind(2, lease_expires_ms);
    RETURN_IF_ERROR(update.Run());
    changed = db.Changes();
    if (changed == 0) return absl::OkStatus();
    return AddEvent(db, now_ms, 0, 0, 0, "leases_extended",
                    absl::StrCat(changed, " open leases extended ", reason));
  });
  if (!status.ok()) return status;
  return changed;
}


absl::StatusOr<std::vector<AttemptRecord>> SqliteStore::ListAttempts(int64_t job_id) {
  absl::MutexLock lock(&read_mutex_);
  ASSIGN_OR_RETURN(Statement query, Statement::Prepare(reader_, R"sql(
SELECT a.attempt, a.state, a.worker_id, a.worker_host, a.worker_build, a.started_ms,
       COALESCE(a.ended_ms, 0), a.lease_expires_ms, a.error,
       (SELECT COUNT(*) FROM episodes e WHERE e.job_id = a.job_id AND e.attempt = a.attempt),
       COALESCE((SELECT c.episode FROM checkpoints c
                 WHERE c.job_id = a.job_id AND c.attempt = a.attempt), -1),
       a.origin
FROM attempts a WHERE a.job_id = ? ORDER BY a.attempt)sql"));
  query.Bind(1, job_id);
  std::vector<AttemptRecord> attempts;
  while (true) {
    ASSIGN_OR_RETURN(bool row, query.Step());
    if (!row) break;
    AttemptRecord a;
    a.key = {job_id, static_cast<int>(query.ColumnInt(0))};
    a.state = ParseAttemptState(query.ColumnText(1)).value_or(AttemptState::kRunning);
    a.worker_id = query.ColumnText(2);
    a.worker_host = query.ColumnText(3);
    a.worker_build = query.ColumnText(4);
    a.started_ms = query.ColumnInt(5);
    a.ended_ms = query.ColumnInt(6);
    a.lease_expires_ms = query.ColumnInt(7);
    a.error = query.ColumnText(8);
    a.episodes_stored = static_cast<int>(query.ColumnInt(9));
    a.checkpoint_episode = static_cast<int>(query.ColumnInt(10));
    a.origin = query.ColumnText(11);
    attempts.push_back(std::move(a));
  }
  return attempts;
}

absl::StatusOr<std::vector<EventRecord>> SqliteStore::ListEvents(int64_t job_id) {
  absl::MutexLock lock(&read_mutex_);
  ASSIGN_OR_RETURN(Statement query,
                   Statement::Prepare(reader_, "SELECT ms, attempt, kind, message FROM events "
                                               "WHERE job_id = ? ORDER BY id"));
  query.Bind(1, job_id);
  std::vector<EventRecord> events;
  while (true) {
    ASSIGN_OR_RETURN(bool row, query.Step());
    if (!row) break;
    events.push_back({query.ColumnInt(0), job_id, static_cast<int>(query.ColumnInt(1)),
                      query.ColumnText(2), query.ColumnText(3)});
  }
  return events;
}

absl::StatusOr<std::optional<CheckpointRecord>> SqliteStore::GetCheckpoint(int64_t job_id,
                                                                           int attempt) {
  absl::MutexLock lock(&read_mutex_);
  ASSIGN_OR_RETURN(Statement query, Statement::Prepare(reader_, R"sql(
SELECT c.attempt, a.worker_build, c.episode, c.format_version, c.data
FROM checkpoints c JOIN attempts a ON a.job_id = c.job_id AND a.attempt = c.attempt
WHERE c.job_id = ? AND (? = 0 OR c.attempt = ?)
ORDER BY c.episode DESC, c.attempt DESC LIMIT 1)sql"));
  query.Bind(1, job_id).Bind(2, attempt).Bind(3, attempt);
  ASSIGN_OR_RETURN(bool row, query.Step());
  if (!row) return std::optional<CheckpointRecord>();
  CheckpointRecord record;
  record.key = {job_id, static_cast<int>(query.ColumnInt(0))};
  record.worker_build = query.ColumnText(1);
  record.checkpoint.episode = static_cast<int>(query.ColumnInt(2));
  record.checkpoint.format_version = static_cast<int>(query.ColumnInt(3));
  record.checkpoint.data = query.ColumnBlob(4);
  return std::optional<CheckpointRecord>(std::move(record));
}


absl::StatusOr<std::vector<LeaseKey>> SqliteStore::ListExpiredLeases(int64_t now_ms) {
  absl::MutexLock lock(&read_mutex_);
  ASSIGN_OR_RETURN(Statement query,
                   Statement::Prepare(reader_, "SELECT job_id, attempt FROM attempts WHERE "
                                               "state = 'running' AND lease_expires_ms < ? "
                                               "ORDER BY lease_expires_ms"));
  query.Bind(1, now_ms);
  std::vector<LeaseKey> keys;
  while (true) {
    ASSIGN_OR_RETURN(bool row, query.Step());
    if (!row) break;
    keys.push_back({query.ColumnInt(0), static_cast<int>(query.ColumnInt(1))});
  }
  return keys;
}


}  // namespace totalgrad::storage
