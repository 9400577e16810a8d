// SqliteStore: sweeps, jobs and workers (sqlite_store.h).
#include <algorithm>
#include <set>
#include <utility>

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

absl::StatusOr<SweepRecord> SqliteStore::CreateSweep(const NewSweep& sweep, int64_t now_ms,
                                                     bool* created) {
  *created = false;
  const absl::Status status = InWriteTransaction(
      [&](Db& db) -> absl::Status { return InsertSweep(db, sweep, now_ms, created); });
  if (!status.ok()) return status;
  return GetSweep(sweep.name);
}

absl::Status SqliteStore::SetSweepState(const std::string& name, SweepState state,
                                        int64_t now_ms) {
  return InWriteTransaction([&](Db& db) -> absl::Status {
    ASSIGN_OR_RETURN(Statement query,
                     Statement::Prepare(db, "SELECT id, state FROM sweeps WHERE name = ?"));
    query.Bind(1, name);
    ASSIGN_OR_RETURN(bool found, query.Step());
    if (!found) return absl::NotFoundError(absl::StrCat("no sweep named '", name, "'"));
    const int64_t sweep_id = query.ColumnInt(0);
    const std::string previous = query.ColumnText(1);
    if (previous == ToString(state)) return absl::OkStatus();
    ASSIGN_OR_RETURN(Statement update,
                     Statement::Prepare(db, "UPDATE sweeps SET state = ? WHERE id = ?"));
    update.Bind(1, ToString(state)).Bind(2, sweep_id);
    RETURN_IF_ERROR(update.Run());
    if (state == SweepState::kCancelled) {
      ASSIGN_OR_RETURN(Statement cancel,
                       Statement::Prepare(db, "UPDATE jobs SET state = 'cancelled' WHERE "
                                              "sweep_id = ? AND state IN ('queued', 'running')"));
      cancel.Bind(1, sweep_id);
      RETURN_IF_ERROR(cancel.Run());
    } else if (previous == ToString(SweepState::kCancelled)) {
      // Resumed by the user: cancelled jobs run again; one whose attempt is
      // still open (its worker has not answered the cancel yet) carries on.
      ASSIGN_OR_RETURN(Statement resume, Statement::Prepare(db, R"sql(
UPDATE jobs SET state = CASE WHEN EXISTS(SELECT 1 FROM attempts a WHERE a.job_id = jobs.id
                                          AND a.attempt = jobs.attempts AND a.state = 'running')
                             THEN 'running' ELSE 'queued' END
WHERE sweep_id = ? AND state = 'cancelled')sql"));
      resume.Bind(1, sweep_id);
      RETURN_IF_ERROR(resume.Run());
    }
    return AddEvent(db, now_ms, sweep_id, 0, 0, absl::StrCat("sweep_", ToString(state)),
                    absl::StrCat("was ", previous));
  });
}


namespace {

// Each checkpoint of a sweep by what reads it: 0 a completed job's counting
// attempt, 1 its other attempts, 2 a job not completed.
constexpr char kCheckpointClass[] = R"sql(CASE WHEN j.state != 'completed' THEN 2
     WHEN c.attempt = j.completed_attempt THEN 0 ELSE 1 END)sql";

// What sweep `name` takes (SweepDiskUse but `removed`); its id into *sweep_id.
absl::Status MeasureSweep(Db& db, const std::string& name, int64_t* sweep_id, SweepDiskUse* use) {
  ASSIGN_OR_RETURN(Statement query, Statement::Prepare(db, "SELECT id FROM sweeps WHERE name = ?"));
  query.Bind(1, name);
  ASSIGN_OR_RETURN(bool found, query.Step());
  if (!found) return absl::NotFoundError(absl::StrCat("no sweep named '", name, "'"));
  *sweep_id = query.ColumnInt(0);
  ASSIGN_OR_RETURN(Statement episodes, Statement::Prepare(db, R"sql(
SELECT COUNT(*), COALESCE(SUM(LENGTH(e.details_json)), 0)
FROM episodes e JOIN jobs j ON j.id = e.job_id WHERE j.sweep_id = ?)sql"));
  episodes.Bind(1, *sweep_id);
  ASSIGN_OR_RETURN(found, episodes.Step());
  use->episodes = episodes.ColumnInt(0);
  use->episode_details_bytes = episodes.ColumnInt(1);
  ASSIGN_OR_RETURN(Statement checkpoints, Statement::Prepare(db, absl::StrCat(
      "SELECT ", kCheckpointClass, " AS class, COUNT(*), COALESCE(SUM(LENGTH(c.data)), 0) "
      "FROM checkpoints c JOIN jobs j ON j.id = c.job_id WHERE j.sweep_id = ? GROUP BY class")));
  checkpoints.Bind(1, *sweep_id);
  CheckpointUse* by_class[] = {&use->completed, &use->stale, &use->unfinished};
  for (;;) {
    ASSIGN_OR_RETURN(bool row, checkpoints.Step());
    if (!row) break;
    CheckpointUse* into = by_class[checkpoints.ColumnInt(0)];
    into->count = static_cast<int>(checkpoints.ColumnInt(1));
    into->bytes = checkpoints.ColumnInt(2);
  }
  return absl::OkStatus();
}

}  // namespace

absl::StatusOr<SweepDiskUse> SqliteStore::PruneCheckpoints(const std::string& name,
                                                          PruneScope scope, int64_t now_ms) {
  SweepDiskUse use;
  int64_t sweep_id = 0;
  if (scope == PruneScope::kNone) {  // a report: a read, so a read-only store answers it too
    absl::MutexLock lock(&read_mutex_);
    RETURN_IF_ERROR(reader_.Exec("BEGIN"));  // one snapshot for every sum
    const absl::Status measured = MeasureSweep(reader_, name, &sweep_id, &use);
    RETURN_IF_ERROR(reader_.Exec("COMMIT"));
    if (!measured.ok()) return measured;
    return use;
  }
  RETURN_IF_ERROR(InWriteTransaction([&](Db& db) -> absl::Status {
    use = SweepDiskUse();
    RETURN_IF_ERROR(MeasureSweep(db, name, &sweep_id, &use));
    use.removed = use.stale;
    if (scope == PruneScope::kCompleted) {
      use.removed.count += use.completed.count;
      use.removed.bytes += use.completed.bytes;
    }
    // Classes removed: 1 (kStale), or 0 and 1 (kCompleted); never 2.
    ASSIGN_OR_RETURN(Statement remove, Statement::Prepare(db, absl::StrCat(
        "DELETE FROM checkpoints WHERE (job_id, attempt) IN (SELECT c.job_id, c.attempt "
        "FROM checkpoints c JOIN jobs j ON j.id = c.job_id WHERE j.sweep_id = ? AND ",
        kCheckpointClass, " BETWEEN ? AND 1)")));
    remove.Bind(1, sweep_id).Bind(2, scope == PruneScope::kCompleted ? 0 : 1);
    RETURN_IF_ERROR(remove.Run());
    return AddEvent(db, now_ms, sweep_id, 0, 0, "checkpoints_pruned",
                    absl::StrCat(use.removed.count, " checkpoints (", use.removed.bytes, " bytes) of ",
                                 scope == PruneScope::kCompleted
                                     ? "completed jobs, their final states included"
                                     : "completed jobs' superseded attempts"));
  }));
  return use;
}

absl::StatusOr<SweepContents> SqliteStore::DeleteSweep(const std::string& name,
                                                      const SweepContents& expected,
                                                      int64_t now_ms) {
  SweepContents deleted;
  RETURN_IF_ERROR(InWriteTransaction([&](Db& db) -> absl::Status {
    ASSIGN_OR_RETURN(Statement query, Statement::Prepare(db, "SELECT id FROM sweeps WHERE name = ?"));
    query.Bind(1, name);
    ASSIGN_OR_RETURN(bool found, query.Step());
    if (!found) return absl::NotFoundError(absl::StrCat("no sweep named '", name, "'"));
    const int64_t sweep_id = query.ColumnInt(0);
    ASSIGN_OR_RETURN(const int64_t open_attempts, QueryInt(db, R"sql(
SELECT COUNT(*) FROM attempts a JOIN jobs j ON j.id = a.job_id
WHERE j.sweep_id = ? AND a.state = 'running')sql", sweep_id));
    if (open_attempts > 0) {
      return absl::FailedPreconditionError(absl::StrCat(
          "sweep '", name, "' has ", open_attempts, " trial(s) running on workers; cancel it "
          "first (totalgrad sweep cancel ", name, ") and delete it once they have stopped"));
    }
    constexpr char kOfSweep[] = "job_id IN (SELECT id FROM jobs WHERE sweep_id = ?)";
    ASSIGN_OR_RETURN(deleted.jobs,
                     QueryInt(db, "SELECT COUNT(*) FROM jobs WHERE sweep_id = ?", sweep_id));
    ASSIGN_OR_RETURN(deleted.attempts,
                     QueryInt(db, absl::StrCat("SELECT COUNT(*) FROM attempts WHERE ", kOfSweep),
                              sweep_id));
    ASSIGN_OR_RETURN(deleted.episodes,
                     QueryInt(db, absl::StrCat("SELECT COUNT(*) FROM episodes WHERE ", kOfSweep),
                              sweep_id));
    ASSIGN_OR_RETURN(const int64_t cells,
                     QueryInt(db, absl::StrCat("SELECT COUNT(*) FROM study_cells WHERE ", kOfSweep),
                              sweep_id));
    ASSIGN_OR_RETURN(const int64_t references,
                     QueryInt(db, absl::StrCat("SELECT COUNT(*) FROM study_references WHERE ",
                                               kOfSweep),
                              sweep_id));
    deleted.study_rows = cells + references;
    if (!(deleted == expected)) {
      return absl::FailedPreconditionError(absl::StrCat(
          "sweep '", name, "' changed after it was archived (now ", deleted.jobs, " jobs, ",
          deleted.attempts, " attempts, ", deleted.episodes, " episodes, ", deleted.study_rows,
          " study rows; the archive has ", expected.jobs, ", ", expected.attempts, ", ",
          expected.episodes, ", ", expected.study_rows, "); nothing was deleted: run the "
          "delete again"));
    }
    // Children first: the foreign keys point from episodes, study rows and
    // checkpoints to attempts, from attempts, options and events to jobs.
    for (const char* table : {"episodes", "study_cells", "study_references", "checkpoints",
                              "attempts", "job_options", "events"}) {
      ASSIGN_OR_RETURN(Statement remove, Statement::Prepare(
          db, absl::StrCat("DELETE FROM ", table, " WHERE ", kOfSweep)));
      remove.Bind(1, sweep_id);
      RETURN_IF_ERROR(remove.Run());
    }
    for (const char* sql : {"DELETE FROM events WHERE sweep_id = ?",
                            "DELETE FROM jobs WHERE sweep_id = ?",
                            "DELETE FROM sweeps WHERE id = ?"}) {
      ASSIGN_OR_RETURN(Statement remove, Statement::Prepare(db, sql));
      remove.Bind(1, sweep_id);
      RETURN_IF_ERROR(remove.Run());
    }
    RETURN_IF_ERROR(internal::DropSweepView(db, name));
    return AddEvent(db, now_ms, 0, 0, 0, "sweep_deleted",
                    absl::StrCat("sweep '", name, "': ", deleted.jobs, " jobs, ",
                                 deleted.attempts, " attempts, ", deleted.episodes,
                                 " episodes, ", deleted.study_rows, " study rows"));
  }));
  return deleted;
}

absl::Status SqliteStore::RetryJob(int64_t job_id, int64_t now_ms) {
  return InWriteTransaction([&](Db& db) -> absl::Status {
    ASSIGN_OR_RETURN(JobRecord job, LoadJob(db, job_id));
    if (job.state != JobState::kFailed && job.state != JobState::kCancelled) {
      return absl::FailedPreconditionError(absl::StrCat(
          "job ", job_id, " is ", ToString(job.state), "; only failed or cancelled jobs can be "
          "retried"));
    }
    if (job.sweep_state == SweepState::kCancelled) {
      // Retrying one job of a cancelled sweep runs that job alone: the sweep
      // runs again, its other cancelled jobs stay cancelled (`sweep resume`
      // re-queues them all). Not while the job's cancelled attempt is still
      // open: its worker has yet to answer the cancel.
      ASSIGN_OR_RETURN(const int64_t open, QueryInt(db, R"sql(
SELECT COUNT(*) FROM attempts WHERE job_id = ? AND state = 'running')sql", job_id));
      if (open > 0) {
        return absl::FailedPreconditionError(absl::StrCat(
            "job ", job_id, " of cancelled sweep '", job.sweep_name, "' is still stopping on its "
            "worker; retry it once it has stopped, or resume the whole sweep (totalgrad sweep "
            "resume ", job.sweep_name, ")"));
      }
      ASSIGN_OR_RETURN(Statement resume, Statement::Prepare(
          db, "UPDATE sweeps SET state = 'running' WHERE id = ?"));
      resume.Bind(1, job.sweep_id);
      RETURN_IF_ERROR(resume.Run());
      RETURN_IF_ERROR(AddEvent(db, now_ms, job.sweep_id, job_id, job.attempts, "sweep_running",
                               absl::StrCat("was cancelled; job ", job_id,
                                            " retried (its other cancelled jobs stay cancelled)")));
    }
    ASSIGN_OR_RETURN(Statement update,
                     Statement::Prepare(db, "UPDATE jobs SET state = 'queued', failures = 0, "
                                            "lost_leases = 0 WHERE id = ?"));
    update.Bind(1, job_id);
    RETURN_IF_ERROR(update.Run());
    return AddEvent(db, now_ms, job.sweep_id, job_id, job.attempts, "retried",
                    absl::StrCat("was ", ToString(job.state)));
  });
}

namespace {

// The columns of `table` other than `except`, comma-joined (so that a copy of
// rows keeps every column a later migration adds).
absl::StatusOr<std::string> ColumnsExcept(Db& db, const std::string& table,
                                          const std::vector<std::string>& except) {
  ASSIGN_OR_RETURN(Statement info, Statement::Prepare(db, absl::StrCat("PRAGMA table_info(", table, ")")));
  std::vector<std::string> columns;
  for (;;) {
    ASSIGN_OR_RETURN(bool row, info.Step());
    if (!row) break;
    std::string name = info.ColumnText(1);
    if (std::find(except.begin(), except.end(), name) == except.end()) columns.push_back(name);
  }
  return absl::StrJoin(columns, ", ");
}

}  // namespace

absl::StatusOr<int> SqliteStore::SupersedeJob(int64_t job_id, int64_t by_job_id, int64_t now_ms) {
  int attempt = 0;
  RETURN_IF_ERROR(InWriteTransaction([&](Db& db) -> absl::Status {
    ASSIGN_OR_RETURN(JobRecord job, LoadJob(db, job_id));
    ASSIGN_OR_RETURN(JobRecord by, LoadJob(db, by_job_id));
    for (const JobRecord* j : {&job, &by}) {
      if (j->kind != JobKind::kTrial || j->state != JobState::kCompleted) {
        return absl::FailedPreconditionError(absl::StrCat(
            "job ", j->id, " is a ", ToString(j->state), " ", ToString(j->kind),
            " job; only a completed trial supersedes, or is superseded by, another"));
      }
    }
    if (job.sweep_id == by.sweep_id) {
      return absl::FailedPreconditionError(absl::StrCat(
          "jobs ", job_id, " and ", by_job_id, " are of the same sweep '", job.sweep_name,
          "': a re-run that supersedes a trial comes from a sweep of its own"));
    }
    if (job.method != by.method || job.seed != by.seed) {
      return absl::FailedPreconditionError(absl::StrCat(
          "job ", job_id, " is ", job.method, " seed ", job.seed, ", job ", by_job_id, " is ",
          by.method, " seed ", by.seed, ": not a re-run of the same trial"));
    }
    const std::string origin = absl::StrCat("job ", by_job_id, " attempt ", by.completed_attempt,
                                            " of sweep ", by.sweep_name);
    // Superseding again by the same re-run changes nothing (a restart script
    // may say it twice, or an imported archive already carry it, under
    // other job ids): the counting attempt is already a copy of that
    // attempt when it names that sweep and ran on the same worker at the
    // same times.
    ASSIGN_OR_RETURN(Statement counting, Statement::Prepare(db, R"sql(
SELECT 1 FROM attempts c JOIN attempts r ON r.job_id = ? AND r.attempt = ?
WHERE c.job_id = ? AND c.attempt = ? AND c.origin LIKE '% of sweep ' || ?
  AND c.worker_id = r.worker_id AND c.worker_build = r.worker_build
  AND c.started_ms = r.started_ms AND c.ended_ms IS r.ended_ms)sql"));
    counting.Bind(1, by_job_id).Bind(2, by.completed_attempt);
    counting.Bind(3, job_id).Bind(4, job.completed_attempt).Bind(5, by.sweep_name);
    ASSIGN_OR_RETURN(bool already, counting.Step());
    if (already) {
      attempt = job.completed_attempt;
      return absl::OkStatus();
    }
    attempt = job.attempts + 1;
    ASSIGN_OR_RETURN(const std::string attempt_columns,
                     ColumnsExcept(db, "attempts", {"job_id", "attempt", "origin"}));
    ASSIGN_OR_RETURN(Statement copy_attempt, Statement::Prepare(db, absl::StrCat(
        "INSERT INTO attempts(job_id, attempt, origin, ", attempt_columns, ") SELECT ?, ?, ?, ",
        attempt_columns, " FROM attempts WHERE job_id = ? AND attempt = ?")));
    copy_attempt.Bind(1, job_id).Bind(2, attempt).Bind(3, origin);
    copy_attempt.Bind(4, by_job_id).Bind(5, by.completed_attempt);
    RETURN_IF_ERROR(copy_attempt.Run());
    for (const char* table : {"episodes", "checkpoints"}) {
      ASSIGN_OR_RETURN(const std::string columns,
                       ColumnsExcept(db, table, {"job_id", "attempt"}));
      ASSIGN_OR_RETURN(Statement copy, Statement::Prepare(db, absl::StrCat(
          "INSERT INTO ", table, "(job_id, attempt, ", columns, ") SELECT ?, ?, ", columns,
          " FROM ", table, " WHERE job_id = ? AND attempt = ?")));
      copy.Bind(1, job_id).Bind(2, attempt).Bind(3, by_job_id).Bind(4, by.completed_attempt);
      RETURN_IF_ERROR(copy.Run());
    }
    ASSIGN_OR_RETURN(Statement update, Statement::Prepare(db, R"sql(
UPDATE jobs SET attempts = ?, completed_attempt = ?, success = ?, final_eval_cost = ?
WHERE id = ?)sql"));
    update.Bind(1, attempt).Bind(2, attempt).Bind(3, by.success ? 1 : 0);
    update.Bind(4, by.final_eval_cost).Bind(5, job_id);
    RETURN_IF_ERROR(update.Run());
    return AddEvent(db, now_ms, job.sweep_id, job_id, attempt, "superseded",
                    absl::StrCat("completed attempt ", job.completed_attempt,
                                 " superseded by ", origin, " (now attempt ", attempt,
                                 "; final cost ", job.final_eval_cost, " -> ",
                                 by.final_eval_cost, ")"));
  }));
  return attempt;
}

absl::Status internal::UpsertWorker(Db& db, const WorkerIdentity& worker, int64_t now_ms) {
  ASSIGN_OR_RETURN(Statement upsert, Statement::Prepare(db, R"sql(
INSERT INTO workers(worker_id, host, build, slots, first_seen_ms, last_seen_ms)
VALUES(?, ?, ?, ?, ?, ?)
ON CONFLICT(worker_id) DO UPDATE SET host = excluded.host, build = excluded.build,
    slots = excluded.slots, last_seen_ms = excluded.last_seen_ms)sql"));
  upsert.Bind(1, worker.worker_id).Bind(2, worker.host).Bind(3, worker.build);
  upsert.Bind(4, worker.slots).Bind(5, now_ms).Bind(6, now_ms);
  return upsert.Run();
}

absl::Status SqliteStore::TouchWorker(const WorkerIdentity& worker, int64_t now_ms) {
  return InWriteTransaction(
      [&](Db& db) -> absl::Status { return internal::UpsertWorker(db, worker, now_ms); });
}

absl::Status SqliteStore::SetWorkerDraining(const std::string& worker_id, bool draining,
                                            int64_t now_ms) {
  return InWriteTransaction([&](Db& db) -> absl::Status {
    ASSIGN_OR_RETURN(Statement update,
                     Statement::Prepare(db, "UPDATE workers SET draining = ? WHERE worker_id = ?"));
    update.Bind(1, draining ? 1 : 0).Bind(2, worker_id);
    RETURN_IF_ERROR(update.Run());
    if (db.Changes() != 1) {
      return absl::NotFoundError(absl::StrCat("no worker with id '", worker_id, "'"));
    }
    return AddEvent(db, now_ms, 0, 0, 0, draining ? "worker_drain" : "worker_undrain", worker_id);
  });
}


absl::StatusOr<SweepRecord> SqliteStore::GetSweep(const std::string& name) {
  absl::MutexLock lock(&read_mutex_);
  return LoadSweep(reader_, name);
}

absl::StatusOr<std::vector<SweepRecord>> SqliteStore::ListSweeps() {
  absl::MutexLock lock(&read_mutex_);
  RETURN_IF_ERROR(reader_.Exec("BEGIN"));  // one snapshot for the whole list
  std::vector<SweepRecord> sweeps;
  absl::Status status = [&]() ABSL_EXCLUSIVE_LOCKS_REQUIRED(read_mutex_) -> absl::Status {
    ASSIGN_OR_RETURN(Statement query,
                     Statement::Prepare(reader_, absl::StrCat(SweepSelectSql(),
                                                              " ORDER BY s.id DESC")));
    while (true) {
      ASSIGN_OR_RETURN(bool row, query.Step());
      if (!row) return absl::OkStatus();
      ASSIGN_OR_RETURN(SweepRecord sweep, ReadSweepRow(reader_, query));
      sweeps.push_back(std::move(sweep));
    }
  }();
  (void)reader_.Exec("COMMIT");
  if (!status.ok()) return status;
  return sweeps;
}

absl::StatusOr<JobRecord> SqliteStore::GetJob(int64_t job_id) {
  absl::MutexLock lock(&read_mutex_);
  return LoadJob(reader_, job_id);
}

absl::StatusOr<JobStatus> SqliteStore::GetJobStatus(int64_t job_id) {
  absl::MutexLock lock(&read_mutex_);
  return internal::ReadJobStatus(reader_, job_id);
}

absl::StatusOr<JobStatus> internal::ReadJobStatus(Db& db, int64_t job_id) {
  ASSIGN_OR_RETURN(Statement query, Statement::Prepare(db, R"sql(
SELECT j.kind, j.state, j.failures, j.lost_leases, s.max_attempts, s.max_lost_leases
FROM jobs j JOIN sweeps s ON s.id = j.sweep_id WHERE j.id = ?)sql"));
  query.Bind(1, job_id);
  ASSIGN_OR_RETURN(bool row, query.Step());
  if (!row) return absl::NotFoundError(absl::StrCat("no job with id ", job_id));
  JobStatus status;
  status.id = job_id;
  const std::optional<JobKind> kind = ParseJobKind(query.ColumnText(0));
  const std::optional<JobState> state = ParseJobState(query.ColumnText(1));
  if (!kind || !state) {
    return absl::DataLossError(absl::StrCat("job ", job_id, " has kind '", query.ColumnText(0),
                                            "' and state '", query.ColumnText(1),
                                            "': not values this build knows"));
  }
  status.kind = *kind;
  status.state = *state;
  status.failures = static_cast<int>(query.ColumnInt(2));
  status.lost_leases = static_cast<int>(query.ColumnInt(3));
  status.max_attempts = static_cast<int>(query.ColumnInt(4));
  status.max_lost_leases = static_cast<int>(query.ColumnInt(5));
  return status;
}

absl::StatusOr<std::vector<JobRecord>> SqliteStore::ListJobs(const JobFilter& filter) {
  absl::MutexLock lock(&read_mutex_);
  // The state filter is one bound parameter: a list ",queued,,running," that
  // each job's state is looked up in with instr().
  std::string states;
  for (JobState s : filter.states) absl::StrAppend(&states, ",", ToString(s), ",");
  ASSIGN_OR_RETURN(Statement query, Statement::Prepare(reader_, absl::StrCat(JobSelectSql(), R"sql(
WHERE (? = '' OR s.name = ?) AND (? = '' OR instr(?, ',' || j.state || ',') > 0) AND j.id > ?
ORDER BY j.id LIMIT ?)sql")));
  query.Bind(1, filter.sweep_name).Bind(2, filter.sweep_name).Bind(3, states).Bind(4, states);
  query.Bind(5, filter.after_job_id).Bind(6, filter.limit);
  std::vector<JobRecord> jobs;
  internal::SharedOptionsCache shared_options;
  while (true) {
    ASSIGN_OR_RETURN(bool row, query.Step());
    if (!row) break;
    jobs.push_back(ReadJobRow(query, &shared_options));
  }
  if (jobs.empty() && !filter.sweep_name.empty()) {
    ASSIGN_OR_RETURN(Statement check,
                     Statement::Prepare(reader_, "SELECT 1 FROM sweeps WHERE name = ?"));
    check.Bind(1, filter.sweep_name);
    ASSIGN_OR_RETURN(bool found, check.Step());
    if (!found) return absl::NotFoundError(absl::StrCat("no sweep named '", filter.sweep_name, "'"));
  }
  return jobs;
}


namespace internal {
// The running sweeps, oldest first, each with its running jobs counted once
// (a handful of rows; the count reads the jobs_by_state index).
const char* ClaimSweepsSql() {
  return R"sql(
SELECT s.id, s.max_concurrent,
       (SELECT COUNT(*) FROM jobs r WHERE r.state = 'running' AND r.sweep_id = s.id)
FROM sweeps s WHERE s.state = 'running' ORDER BY s.id)sql";
}
// One sweep's first queued jobs in ordinal order, straight from the
// jobs_by_state index: as cheap with 1,000 as with 1,000,000 jobs queued.
// (One query joining jobs to sweeps read every queued job and sorted them
// for each lease: 36 ms of coordinator CPU per job with 100,000 queued.)
const char* ClaimJobsSql() {
  return R"sql(
SELECT id, attempts, kind FROM jobs WHERE state = 'queued' AND sweep_id = ?
ORDER BY ordinal LIMIT ?)sql";
}
}  // namespace internal



namespace {
constexpr char kWorkerSelect[] = R"sql(
SELECT w.worker_id, w.host, w.build, w.slots, w.first_seen_ms, w.last_seen_ms, w.draining,
       (SELECT COUNT(*) FROM attempts a WHERE a.worker_id = w.worker_id AND a.state = 'running')
FROM workers w)sql";

WorkerRecord ReadWorkerRow(const Statement& query) {
  WorkerRecord w;
  w.identity.worker_id = query.ColumnText(0);
  w.identity.host = query.ColumnText(1);
  w.identity.build = query.ColumnText(2);
  w.identity.slots = static_cast<int>(query.ColumnInt(3));
  w.first_seen_ms = query.ColumnInt(4);
  w.last_seen_ms = query.ColumnInt(5);
  w.draining = query.ColumnInt(6) != 0;
  w.running = static_cast<int>(query.ColumnInt(7));
  return w;
}
}  // namespace

absl::StatusOr<std::vector<WorkerRecord>> SqliteStore::ListWorkers() {
  absl::MutexLock lock(&read_mutex_);
  ASSIGN_OR_RETURN(Statement query,
                   Statement::Prepare(reader_, absl::StrCat(kWorkerSelect,
                                                            " ORDER BY w.last_seen_ms DESC")));
  std::vector<WorkerRecord> workers;
  while (true) {
    ASSIGN_OR_RETURN(bool row, query.Step());
    if (!row) break;
    workers.push_back(ReadWorkerRow(query));
  }
  return workers;
}

absl::StatusOr<WorkerRecord> SqliteStore::GetWorker(const std::string& worker_id) {
  absl::MutexLock lock(&read_mutex_);
  ASSIGN_OR_RETURN(Statement query,
                   Statement::Prepare(reader_, absl::StrCat(kWorkerSelect,
                                                            " WHERE w.worker_id = ?")));
  query.Bind(1, worker_id);
  ASSIGN_OR_RETURN(bool row, query.Step());
  if (!row) return absl::NotFoundError(absl::StrCat("no worker with id '", worker_id, "'"));
  return ReadWorkerRow(query);
}


}  // namespace totalgrad::storage
