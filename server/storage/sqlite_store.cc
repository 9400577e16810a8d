#include "server/storage/sqlite_store.h"

#include <fcntl.h>
#include <sqlite3.h>
#include <sys/file.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <filesystem>
#include <nlohmann/json.hpp>
#include <set>
#include <utility>

#include "absl/strings/str_cat.h"
#include "absl/strings/str_join.h"
#include "server/common/status_macros.h"
#include "server/storage/sqlite_schema.h"

namespace totalgrad::storage {
namespace {

using internal::Db;
using internal::kSchemaVersion;
using internal::Migrate;
using internal::Statement;

// The first four columns of both study-row queries: job, attempt, the job's
// study name, and whether this attempt is the job's completed one.
template <typename StudyRecord>
void ReadStudyRowHeader(Statement& query, StudyRecord* record) {
  record->job_id = query.ColumnInt(0);
  record->attempt = static_cast<int>(query.ColumnInt(1));
  record->study = query.ColumnText(2);
  record->final_attempt = query.ColumnInt(3) != 0;
}

// Doubles as JSON arrays: round-trip precision; NaN and +-Inf as null.
std::string DoublesToJson(const std::vector<double>& values) {
  nlohmann::json array = nlohmann::json::array();
  for (double v : values) array.push_back(std::isfinite(v) ? nlohmann::json(v) : nlohmann::json());
  return array.dump();
}
std::vector<double> DoublesFromJson(const std::string& text) {
  std::vector<double> values;
  const nlohmann::json array = nlohmann::json::parse(text, nullptr, /*allow_exceptions=*/false);
  if (!array.is_array()) return values;
  for (const auto& v : array) values.push_back(v.is_number() ? v.get<double>() : kNaN);
  return values;
}

std::optional<JobKind> ParseJobKind(absl::string_view text) {
  if (text == "trial") return JobKind::kTrial;
  if (text == "study") return JobKind::kStudy;
  return std::nullopt;
}

std::string OptionsToJson(const OptionList& options) {
  nlohmann::json array = nlohmann::json::array();
  for (const auto& [key, value] : options) array.push_back({key, value});
  return array.dump();
}

OptionList OptionsFromJson(const std::string& text) {
  OptionList options;
  const nlohmann::json array = nlohmann::json::parse(text, nullptr, /*allow_exceptions=*/false);
  if (!array.is_array()) return options;
  for (const auto& pair : array) {
    if (pair.is_array() && pair.size() == 2 && pair[0].is_string() && pair[1].is_string()) {
      options.emplace_back(pair[0].get<std::string>(), pair[1].get<std::string>());
    }
  }
  return options;
}

absl::Status AddEvent(Db& db, int64_t ms, int64_t sweep_id, int64_t job_id, int attempt,
                      absl::string_view kind, absl::string_view message) {
  ASSIGN_OR_RETURN(Statement insert,
                   Statement::Prepare(db, "INSERT INTO events(ms, sweep_id, job_id, attempt, kind, "
                                          "message) VALUES(?, ?, ?, ?, ?, ?)"));
  insert.Bind(1, ms);
  if (sweep_id > 0) insert.Bind(2, sweep_id); else insert.BindNull(2);
  if (job_id > 0) insert.Bind(3, job_id); else insert.BindNull(3);
  insert.Bind(4, attempt).Bind(5, kind).Bind(6, message);
  return insert.Run();
}

// Reads an int from a one-row query.
absl::StatusOr<int64_t> QueryInt(Db& db, absl::string_view sql, int64_t param) {
  ASSIGN_OR_RETURN(Statement query, Statement::Prepare(db, sql));
  query.Bind(1, param);
  ASSIGN_OR_RETURN(bool row, query.Step());
  if (!row) return int64_t{0};
  return query.ColumnInt(0);
}

constexpr char kSweepColumns[] =
    "s.id, s.name, s.description, s.state, s.canonical_spec, s.spec_hash, s.source_name, "
    "s.coordinator_build, s.created_ms, s.max_attempts, s.max_lost_leases, s.max_concurrent";

absl::StatusOr<SweepRecord> ReadSweepRow(Db& db, const Statement& row) {
  SweepRecord sweep;
  sweep.id = row.ColumnInt(0);
  sweep.name = row.ColumnText(1);
  sweep.description = row.ColumnText(2);
  sweep.state = ParseSweepState(row.ColumnText(3)).value_or(SweepState::kRunning);
  sweep.canonical_spec = row.ColumnText(4);
  sweep.spec_hash = row.ColumnText(5);
  sweep.source_name = row.ColumnText(6);
  sweep.coordinator_build = row.ColumnText(7);
  sweep.created_ms = row.ColumnInt(8);
  sweep.max_attempts = static_cast<int>(row.ColumnInt(9));
  sweep.max_lost_leases = static_cast<int>(row.ColumnInt(10));
  sweep.max_concurrent = static_cast<int>(row.ColumnInt(11));
  ASSIGN_OR_RETURN(Statement counts,
                   Statement::Prepare(db, "SELECT state, COUNT(*), SUM(CASE WHEN kind = 'study' THEN 0 "
                                          "ELSE episodes_expected END) "
                                          "FROM jobs WHERE sweep_id = ? GROUP BY state"));
  counts.Bind(1, sweep.id);
  while (true) {
    ASSIGN_OR_RETURN(bool more, counts.Step());
    if (!more) break;
    const int n = static_cast<int>(counts.ColumnInt(1));
    sweep.jobs_total += n;
    sweep.episodes_expected += counts.ColumnInt(2);
    switch (ParseJobState(counts.ColumnText(0)).value_or(JobState::kQueued)) {
      case JobState::kQueued: sweep.jobs_queued += n; break;
      case JobState::kRunning: sweep.jobs_running += n; break;
      case JobState::kCompleted: sweep.jobs_completed += n; break;
      case JobState::kFailed: sweep.jobs_failed += n; break;
      case JobState::kCancelled: sweep.jobs_cancelled += n; break;
    }
  }
  ASSIGN_OR_RETURN(
      sweep.episodes_stored,
      QueryInt(db,
               "SELECT COUNT(*) FROM episodes e JOIN jobs j ON e.job_id = j.id AND "
               "e.attempt = COALESCE(j.completed_attempt, j.attempts) WHERE j.sweep_id = ?",
               sweep.id));
  return sweep;
}

absl::StatusOr<SweepRecord> LoadSweep(Db& db, const std::string& name) {
  ASSIGN_OR_RETURN(Statement query,
                   Statement::Prepare(db, absl::StrCat("SELECT ", kSweepColumns,
                                                       " FROM sweeps s WHERE s.name = ?")));
  query.Bind(1, name);
  ASSIGN_OR_RETURN(bool row, query.Step());
  if (!row) return absl::NotFoundError(absl::StrCat("no sweep named '", name, "'"));
  return ReadSweepRow(db, query);
}

constexpr char kJobSelect[] = R"sql(
SELECT j.id, j.sweep_id, s.name, s.state, j.ordinal, j.method, j.seed, j.variant, j.options_json,
       j.state, j.attempts, j.failures, j.lost_leases, s.max_attempts, s.max_lost_leases,
       CASE WHEN j.kind = 'study' THEN 0 ELSE j.episodes_expected END,
       (SELECT COUNT(*) FROM episodes e WHERE e.job_id = j.id AND e.attempt = j.attempts),
       COALESCE((SELECT a.worker_id FROM attempts a
                 WHERE a.job_id = j.id AND a.attempt = j.attempts AND a.state = 'running'), ''),
       j.last_error, COALESCE(j.completed_attempt, 0), COALESCE(j.success, 0), j.final_eval_cost,
       j.kind, j.payload
FROM jobs j JOIN sweeps s ON s.id = j.sweep_id
)sql";

JobRecord ReadJobRow(const Statement& row) {
  JobRecord job;
  job.id = row.ColumnInt(0);
  job.sweep_id = row.ColumnInt(1);
  job.sweep_name = row.ColumnText(2);
  job.sweep_state = ParseSweepState(row.ColumnText(3)).value_or(SweepState::kRunning);
  job.ordinal = static_cast<int>(row.ColumnInt(4));
  job.method = row.ColumnText(5);
  job.seed = row.ColumnText(6);
  job.variant = row.ColumnText(7);
  job.options = OptionsFromJson(row.ColumnText(8));
  job.state = ParseJobState(row.ColumnText(9)).value_or(JobState::kQueued);
  job.attempts = static_cast<int>(row.ColumnInt(10));
  job.failures = static_cast<int>(row.ColumnInt(11));
  job.lost_leases = static_cast<int>(row.ColumnInt(12));
  job.max_attempts = static_cast<int>(row.ColumnInt(13));
  job.max_lost_leases = static_cast<int>(row.ColumnInt(14));
  job.episodes_expected = static_cast<int>(row.ColumnInt(15));
  job.episodes_stored = static_cast<int>(row.ColumnInt(16));
  job.worker_id = row.ColumnText(17);
  job.last_error = row.ColumnText(18);
  job.completed_attempt = static_cast<int>(row.ColumnInt(19));
  job.success = row.ColumnInt(20) != 0;
  job.final_eval_cost = row.ColumnDouble(21);
  job.kind = ParseJobKind(row.ColumnText(22)).value_or(JobKind::kTrial);
  job.payload = row.ColumnText(23);
  return job;
}

absl::StatusOr<JobRecord> LoadJob(Db& db, int64_t job_id) {
  ASSIGN_OR_RETURN(Statement query,
                   Statement::Prepare(db, absl::StrCat(kJobSelect, " WHERE j.id = ?")));
  query.Bind(1, job_id);
  ASSIGN_OR_RETURN(bool row, query.Step());
  if (!row) return absl::NotFoundError(absl::StrCat("no job with id ", job_id));
  return ReadJobRow(query);
}

struct OpenAttempt {
  JobKind kind = JobKind::kTrial;
  AttemptState state = AttemptState::kRunning;
  std::string worker_id;
  int job_attempts = 0;
  int episodes_expected = 0;
  int64_t sweep_id = 0;
};

// Loads the attempt and the job's latest attempt number. NotFound if the job
// does not exist; Aborted if the attempt does not exist.
absl::StatusOr<OpenAttempt> LoadAttempt(Db& db, const LeaseKey& key) {
  ASSIGN_OR_RETURN(Statement query,
                   Statement::Prepare(db, "SELECT j.attempts, CASE WHEN j.kind = 'study' THEN 0 "
                                          "ELSE j.episodes_expected END, j.sweep_id, "
                                          "a.state, a.worker_id, j.kind FROM jobs j LEFT JOIN "
                                          "attempts a ON a.job_id = j.id AND a.attempt = ? "
                                          "WHERE j.id = ?"));
  query.Bind(1, key.attempt).Bind(2, key.job_id);
  ASSIGN_OR_RETURN(bool row, query.Step());
  if (!row) return absl::NotFoundError(absl::StrCat("no job with id ", key.job_id));
  OpenAttempt attempt;
  attempt.job_attempts = static_cast<int>(query.ColumnInt(0));
  attempt.episodes_expected = static_cast<int>(query.ColumnInt(1));
  attempt.sweep_id = query.ColumnInt(2);
  attempt.kind = ParseJobKind(query.ColumnText(5)).value_or(JobKind::kTrial);
  if (query.ColumnIsNull(3)) {
    return absl::AbortedError(absl::StrCat("job ", key.job_id, " has no attempt ", key.attempt,
                                           " (latest is ", attempt.job_attempts, ")"));
  }
  attempt.state = ParseAttemptState(query.ColumnText(3)).value_or(AttemptState::kRunning);
  attempt.worker_id = query.ColumnText(4);
  return attempt;
}

// The fence: the attempt must be open, the job's latest, and owned by `worker_id`.
absl::Status CheckOpen(const LeaseKey& key, const OpenAttempt& attempt,
                       const std::string& worker_id) {
  if (attempt.state != AttemptState::kRunning) {
    return absl::AbortedError(absl::StrCat("lease of job ", key.job_id, " attempt ", key.attempt,
                                           " is no longer held: the attempt ended as ",
                                           ToString(attempt.state)));
  }
  if (attempt.job_attempts != key.attempt) {
    return absl::AbortedError(absl::StrCat("lease of job ", key.job_id, " attempt ", key.attempt,
                                           " is stale: the job is at attempt ",
                                           attempt.job_attempts));
  }
  if (attempt.worker_id != worker_id) {
    return absl::AbortedError(absl::StrCat("lease of job ", key.job_id, " attempt ", key.attempt,
                                           " belongs to worker '", attempt.worker_id,
                                           "', not '", worker_id, "'"));
  }
  return absl::OkStatus();
}

absl::Status InsertEpisodes(Db& db, const LeaseKey& key, int episodes_expected,
                            const std::vector<Episode>& episodes, int64_t now_ms) {
  if (episodes.empty()) return absl::OkStatus();
  ASSIGN_OR_RETURN(Statement insert,
                   Statement::Prepare(db, R"sql(
INSERT INTO episodes(job_id, attempt, episode, real_cost, eval_cost_mean, eval_cost_std,
                     predicted_cost, optimisation_seconds, details_json, reported_ms, cpu_seconds)
VALUES(?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?)
ON CONFLICT(job_id, attempt, episode) DO NOTHING)sql"));
  for (const Episode& episode : episodes) {
    if (episodes_expected == 0) {
      return absl::InvalidArgumentError(absl::StrCat(
          "job ", key.job_id, " is a study job; it reports study rows, not episodes"));
    }
    if (episode.episode < 0 || episode.episode >= episodes_expected) {
      return absl::InvalidArgumentError(
          absl::StrCat("episode ", episode.episode, " of job ", key.job_id,
                       " is out of range: the trial has episodes 0..", episodes_expected - 1));
    }
    insert.Bind(1, key.job_id).Bind(2, key.attempt).Bind(3, episode.episode);
    insert.Bind(4, episode.real_cost).Bind(5, episode.eval_cost_mean);
    insert.Bind(6, episode.eval_cost_std).Bind(7, episode.predicted_cost);
    insert.Bind(8, episode.optimisation_seconds).Bind(9, episode.details_json).Bind(10, now_ms);
    insert.Bind(11, episode.cpu_seconds);
    RETURN_IF_ERROR(insert.Run());
    insert.Reset();
  }
  return absl::OkStatus();
}

absl::Status InsertStudyRows(Db& db, const LeaseKey& key, JobKind kind, const StudyRows& rows,
                             int64_t now_ms) {
  if (rows.empty()) return absl::OkStatus();
  if (kind != JobKind::kStudy) {
    return absl::InvalidArgumentError(absl::StrCat(
        "job ", key.job_id, " is a trial job; study rows belong to study jobs"));
  }
  if (!rows.cells.empty()) {
    ASSIGN_OR_RETURN(Statement insert, Statement::Prepare(db, R"sql(
INSERT INTO study_cells(job_id, attempt, idx, estimator, method, particles, horizon, replicates,
    nonfinite, errors, time_min_s, time_median_s, rel_rmse, rel_bias, rel_bias_noise,
    total_variance, cos_mean, objective_mean, ess_mean, ess_min, k_lr_mean, reference_agrees,
    reference_floor, budget_hit, omitted, note, error, omission_reason, k_lr_per_step_json,
    reported_ms)
VALUES(?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?)
ON CONFLICT(job_id, attempt, idx) DO NOTHING)sql"));
    for (const StudyCell& c : rows.cells) {
      if (c.index < 0) {
        return absl::InvalidArgumentError(
            absl::StrCat("study cell index ", c.index, " of job ", key.job_id, " is negative"));
      }
      insert.Bind(1, key.job_id).Bind(2, key.attempt).Bind(3, c.index).Bind(4, c.estimator);
      insert.Bind(5, c.method).Bind(6, c.particles).Bind(7, c.horizon).Bind(8, c.replicates);
      insert.Bind(9, c.nonfinite).Bind(10, c.errors).Bind(11, c.time_min_s);
      insert.Bind(12, c.time_median_s).Bind(13, c.rel_rmse).Bind(14, c.rel_bias);
      insert.Bind(15, c.rel_bias_noise).Bind(16, c.total_variance).Bind(17, c.cos_mean);
      insert.Bind(18, c.objective_mean).Bind(19, c.ess_mean).Bind(20, c.ess_min);
      insert.Bind(21, c.k_lr_mean).Bind(22, c.reference_agrees ? 1 : 0);
      insert.Bind(23, c.reference_floor).Bind(24, c.budget_hit ? 1 : 0);
      insert.Bind(25, c.omitted ? 1 : 0).Bind(26, c.note).Bind(27, c.error);
      insert.Bind(28, c.omission_reason).Bind(29, DoublesToJson(c.k_lr_per_step));
      insert.Bind(30, now_ms);
      RETURN_IF_ERROR(insert.Run());
      insert.Reset();
    }
  }
  if (!rows.references.empty()) {
    ASSIGN_OR_RETURN(Statement insert, Statement::Prepare(db, R"sql(
INSERT INTO study_references(job_id, attempt, idx, horizon, norm, relative_error, floor,
    objective, used_json, replicates_json, agreement_max_z, agreement_mean_z2, agree, seconds,
    note, gradient_json, standard_error_json, reported_ms)
VALUES(?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?)
ON CONFLICT(job_id, attempt, idx) DO NOTHING)sql"));
    for (const StudyReference& r : rows.references) {
      if (r.index < 0) {
        return absl::InvalidArgumentError(absl::StrCat(
            "study reference index ", r.index, " of job ", key.job_id, " is negative"));
      }
      insert.Bind(1, key.job_id).Bind(2, key.attempt).Bind(3, r.index).Bind(4, r.horizon);
      insert.Bind(5, r.norm).Bind(6, r.relative_error).Bind(7, r.floor).Bind(8, r.objective);
      insert.Bind(9, nlohmann::json(r.used).dump()).Bind(10, nlohmann::json(r.replicates).dump());
      insert.Bind(11, r.agreement_max_z).Bind(12, r.agreement_mean_z2).Bind(13, r.agree ? 1 : 0);
      insert.Bind(14, r.seconds).Bind(15, r.note).Bind(16, DoublesToJson(r.gradient));
      insert.Bind(17, DoublesToJson(r.standard_error)).Bind(18, now_ms);
      RETURN_IF_ERROR(insert.Run());
      insert.Reset();
    }
  }
  return absl::OkStatus();
}

absl::StatusOr<int> CountStudyRows(Db& db, const LeaseKey& key) {
  ASSIGN_OR_RETURN(Statement count, Statement::Prepare(db, R"sql(
SELECT (SELECT COUNT(*) FROM study_cells WHERE job_id = ?1 AND attempt = ?2) +
       (SELECT COUNT(*) FROM study_references WHERE job_id = ?1 AND attempt = ?2))sql"));
  count.Bind(1, key.job_id).Bind(2, key.attempt);
  ASSIGN_OR_RETURN(bool row, count.Step());
  return row ? static_cast<int>(count.ColumnInt(0)) : 0;
}

// The indexes in 0..total-1 missing from `table` for the attempt.
absl::StatusOr<std::vector<int>> MissingStudyRows(Db& db, const LeaseKey& key,
                                                  absl::string_view table, int total) {
  ASSIGN_OR_RETURN(Statement present,
                   Statement::Prepare(db, absl::StrCat("SELECT idx FROM ", table,
                                                       " WHERE job_id = ? AND attempt = ? "
                                                       "AND idx < ?")));
  present.Bind(1, key.job_id).Bind(2, key.attempt).Bind(3, total);
  std::set<int> have;
  while (true) {
    ASSIGN_OR_RETURN(bool row, present.Step());
    if (!row) break;
    have.insert(static_cast<int>(present.ColumnInt(0)));
  }
  std::vector<int> missing;
  for (int i = 0; i < total; ++i) {
    if (!have.count(i)) missing.push_back(i);
  }
  return missing;
}

// Keeps `checkpoint` for the attempt unless it holds one of a later episode.
absl::Status UpsertCheckpoint(Db& db, const LeaseKey& key, const OpenAttempt& attempt,
                              const Checkpoint& checkpoint, int64_t now_ms) {
  if (attempt.kind != JobKind::kTrial) {
    return absl::InvalidArgumentError(
        absl::StrCat("job ", key.job_id, " is a study job; only trials have checkpoints"));
  }
  if (checkpoint.episode < 0 || checkpoint.episode >= attempt.episodes_expected) {
    return absl::InvalidArgumentError(absl::StrCat(
        "checkpoint after episode ", checkpoint.episode, " of job ", key.job_id,
        " is out of range: the trial has episodes 0..", attempt.episodes_expected - 1));
  }
  ASSIGN_OR_RETURN(Statement upsert, Statement::Prepare(db, R"sql(
INSERT INTO checkpoints(job_id, attempt, episode, format_version, data, reported_ms)
VALUES(?, ?, ?, ?, ?, ?)
ON CONFLICT(job_id, attempt) DO UPDATE SET episode = excluded.episode,
    format_version = excluded.format_version, data = excluded.data,
    reported_ms = excluded.reported_ms
WHERE excluded.episode >= checkpoints.episode)sql"));
  upsert.Bind(1, key.job_id).Bind(2, key.attempt).Bind(3, checkpoint.episode);
  upsert.Bind(4, checkpoint.format_version).BindBlob(5, checkpoint.data).Bind(6, now_ms);
  return upsert.Run();
}

}  // namespace

// ---- enum names ----

absl::string_view ToString(SweepState state) {
  switch (state) {
    case SweepState::kRunning: return "running";
    case SweepState::kPaused: return "paused";
    case SweepState::kCancelled: return "cancelled";
  }
  return "unknown";
}
absl::string_view ToString(JobState state) {
  switch (state) {
    case JobState::kQueued: return "queued";
    case JobState::kRunning: return "running";
    case JobState::kCompleted: return "completed";
    case JobState::kFailed: return "failed";
    case JobState::kCancelled: return "cancelled";
  }
  return "unknown";
}
absl::string_view ToString(AttemptState state) {
  switch (state) {
    case AttemptState::kRunning: return "running";
    case AttemptState::kCompleted: return "completed";
    case AttemptState::kFailed: return "failed";
    case AttemptState::kLeaseLost: return "lease_lost";
    case AttemptState::kReleased: return "released";
    case AttemptState::kCancelled: return "cancelled";
  }
  return "unknown";
}
absl::string_view ToString(JobKind kind) {
  return kind == JobKind::kStudy ? "study" : "trial";
}
std::optional<SweepState> ParseSweepState(absl::string_view text) {
  for (SweepState s : {SweepState::kRunning, SweepState::kPaused, SweepState::kCancelled}) {
    if (ToString(s) == text) return s;
  }
  return std::nullopt;
}
std::optional<JobState> ParseJobState(absl::string_view text) {
  for (JobState s : {JobState::kQueued, JobState::kRunning, JobState::kCompleted,
                     JobState::kFailed, JobState::kCancelled}) {
    if (ToString(s) == text) return s;
  }
  return std::nullopt;
}
std::optional<AttemptState> ParseAttemptState(absl::string_view text) {
  for (AttemptState s : {AttemptState::kRunning, AttemptState::kCompleted, AttemptState::kFailed,
                         AttemptState::kLeaseLost, AttemptState::kReleased,
                         AttemptState::kCancelled}) {
    if (ToString(s) == text) return s;
  }
  return std::nullopt;
}

// ---- SqliteStore ----

namespace {

int64_t SteadyMs() {
  return std::chrono::duration_cast<std::chrono::milliseconds>(
             std::chrono::steady_clock::now().time_since_epoch())
      .count();
}

std::string HostName() {
  char buffer[256] = {};
  if (gethostname(buffer, sizeof(buffer) - 1) != 0) return "unknown-host";
  return buffer;
}

std::string ErrnoText(int error) { return std::strerror(error); }

// The exclusive lock beside the database. Returns its descriptor, and in
// *recorded what the previous holder wrote (empty if nothing).
absl::StatusOr<int> TakeLock(const std::string& path, std::string* recorded) {
  const std::string lock_path = absl::StrCat(path, ".lock");
  const int fd = ::open(lock_path.c_str(), O_RDWR | O_CREAT | O_CLOEXEC, 0600);
  if (fd < 0) {
    return absl::FailedPreconditionError(absl::StrCat(
        "cannot open the lock file ", lock_path, ": ", ErrnoText(errno),
        " (the database's directory must be writable)"));
  }
  char buffer[4096];
  const ssize_t n = ::pread(fd, buffer, sizeof(buffer) - 1, 0);
  recorded->assign(buffer, n > 0 ? static_cast<size_t>(n) : 0);
  if (::flock(fd, LOCK_EX | LOCK_NB) != 0) {
    const int error = errno;
    ::close(fd);
    if (error == EWOULDBLOCK) {
      std::string holder = recorded->substr(0, recorded->find('\n'));
      return absl::FailedPreconditionError(absl::StrCat(
          "database ", path, " is in use by another coordinator (",
          holder.empty() ? "holder unknown" : holder, "; lock file ", lock_path,
          "); stop it first, or use a copy (--backup) for reading"));
    }
    return absl::FailedPreconditionError(
        absl::StrCat("cannot lock ", lock_path, ": ", ErrnoText(error)));
  }
  return fd;
}

// Rewrites the lock file: who holds it, and which file is the database.
void RecordHolder(int fd, const std::string& path, uint64_t device, uint64_t inode) {
  const auto now = std::chrono::duration_cast<std::chrono::seconds>(
                       std::chrono::system_clock::now().time_since_epoch())
                       .count();
  const std::string text =
      absl::StrCat("pid ", getpid(), " on host ", HostName(), " since unix time ", now,
                   "\ndatabase ", path, " device:inode ", device, ":", inode, "\n");
  if (::ftruncate(fd, 0) == 0) (void)!::pwrite(fd, text.data(), text.size(), 0);
  ::fsync(fd);
}

// What is at `path` before anything is written to it.
enum class FileKind { kMissing, kEmpty, kEmptySqlite, kTotalgrad, };
struct Inspection {
  FileKind kind = FileKind::kMissing;
  int64_t version = 0;
};

// Looks at the file through a read-only connection. FailedPrecondition for a
// foreign file or a newer schema (nothing is written in either case).
absl::StatusOr<Inspection> InspectFile(const std::string& path, int busy_timeout_ms) {
  Inspection inspection;
  struct stat st;
  if (::stat(path.c_str(), &st) != 0) {
    if (errno == ENOENT) return inspection;
    return absl::FailedPreconditionError(absl::StrCat("cannot stat ", path, ": ", ErrnoText(errno)));
  }
  if (!S_ISREG(st.st_mode)) {
    return absl::FailedPreconditionError(absl::StrCat(path, " is not a regular file"));
  }
  if (st.st_size == 0) {
    inspection.kind = FileKind::kEmpty;
    return inspection;
  }
  {
    char header[16] = {};
    std::ifstream in(path, std::ios::binary);
    in.read(header, sizeof(header));
    if (!in || std::memcmp(header, "SQLite format 3", 16) != 0) {
      return absl::FailedPreconditionError(absl::StrCat(
          path, " is not an SQLite database (a foreign file); refusing to touch it. Give --db a "
                "new path, or the right one"));
    }
  }
  ASSIGN_OR_RETURN(Db reader, Db::OpenReadOnly(path, busy_timeout_ms));
  ASSIGN_OR_RETURN(Statement version, Statement::Prepare(reader, "PRAGMA user_version"));
  ASSIGN_OR_RETURN(bool row, version.Step());
  inspection.version = row ? version.ColumnInt(0) : 0;
  ASSIGN_OR_RETURN(Statement tables, Statement::Prepare(reader, "SELECT COUNT(*) FROM sqlite_schema"));
  ASSIGN_OR_RETURN(row, tables.Step());
  const int64_t table_count = row ? tables.ColumnInt(0) : 0;
  if (inspection.version == 0) {
    if (table_count != 0) {
      return absl::FailedPreconditionError(absl::StrCat(
          path, " is an SQLite database but not a totalgrad one (it has tables and no totalgrad "
                "schema version); refusing to touch it"));
    }
    inspection.kind = FileKind::kEmptySqlite;
    return inspection;
  }
  if (inspection.version > kSchemaVersion) {
    return absl::FailedPreconditionError(absl::StrCat(
        path, " has totalgrad schema version ", inspection.version, "; this build reads version ",
        kSchemaVersion, " and older (the file was not changed): use a newer build"));
  }
  inspection.kind = FileKind::kTotalgrad;
  return inspection;
}

// Copies the database at `source` (read through `reader`) into `target`.
absl::StatusOr<int64_t> CopyDatabase(Db& source, const std::string& target, int busy_timeout_ms) {
  std::error_code error;
  if (std::filesystem::exists(target, error)) {
    return absl::AlreadyExistsError(absl::StrCat("backup target ", target, " already exists"));
  }
  // Copy into a temporary name and rename, so a crash never leaves a
  // half-written file under the requested name.
  const std::string temporary = absl::StrCat(target, ".partial");
  std::filesystem::remove(temporary, error);
  absl::Status status;
  {
    ASSIGN_OR_RETURN(Db destination, Db::Open(temporary, /*create=*/true, busy_timeout_ms));
    sqlite3_backup* backup = sqlite3_backup_init(destination.raw(), "main", source.raw(), "main");
    if (backup == nullptr) {
      return internal::SqliteError(sqlite3_errcode(destination.raw()), "backup init",
                                   sqlite3_errmsg(destination.raw()));
    }
    // One step copies everything from one read snapshot: the copy is
    // consistent even while the writer keeps committing.
    const int rc = sqlite3_backup_step(backup, -1);
    sqlite3_backup_finish(backup);
    if (rc != SQLITE_DONE) {
      status = internal::SqliteError(rc, "backup step", sqlite3_errstr(rc));
    } else {
      status = destination.Exec("PRAGMA journal_mode=DELETE");
    }
  }
  if (!status.ok()) {
    std::filesystem::remove(temporary, error);
    return status;
  }
  std::filesystem::rename(temporary, target, error);
  if (error) {
    return absl::InternalError(absl::StrCat("backup: rename ", temporary, " -> ", target, ": ",
                                            error.message()));
  }
  const auto size = std::filesystem::file_size(target, error);
  return error ? int64_t{0} : static_cast<int64_t>(size);
}

// Storage failures (as opposed to a refusal of the request itself).
bool IsDatabaseFailure(const absl::Status& status) {
  switch (status.code()) {
    case absl::StatusCode::kUnavailable:
    case absl::StatusCode::kDataLoss:
    case absl::StatusCode::kInternal:
    case absl::StatusCode::kResourceExhausted:
      return true;
    default:
      return false;
  }
}

// CreateSweep inside the caller's transaction: *created tells whether it
// was inserted (false: a sweep of that name and hash existed).
absl::Status InsertSweep(Db& db, const NewSweep& sweep, int64_t now_ms, bool* created) {
  *created = false;
    ASSIGN_OR_RETURN(Statement existing,
                   Statement::Prepare(db, "SELECT spec_hash FROM sweeps WHERE name = ?"));
  existing.Bind(1, sweep.name);
  ASSIGN_OR_RETURN(bool found, existing.Step());
  if (found) {
    const std::string stored = existing.ColumnText(0);
    if (stored != sweep.spec_hash &&
        std::find(sweep.equivalent_spec_hashes.begin(), sweep.equivalent_spec_hashes.end(),
                  stored) == sweep.equivalent_spec_hashes.end()) {
      return absl::AlreadyExistsError(absl::StrCat(
          "a different sweep named '", sweep.name, "' exists (spec hash ",
          existing.ColumnText(0).substr(0, 12), ", submitted ", sweep.spec_hash.substr(0, 12),
          "); rename the sweep or cancel and use a new name"));
    }
    return absl::OkStatus();
  }
  ASSIGN_OR_RETURN(Statement insert, Statement::Prepare(db, R"sql(
INSERT INTO sweeps(name, description, state, canonical_spec, spec_hash, source_name, source_text,
                 coordinator_build, max_attempts, max_lost_leases, max_concurrent, created_ms)
VALUES(?, ?, 'running', ?, ?, ?, ?, ?, ?, ?, ?, ?))sql"));
  insert.Bind(1, sweep.name).Bind(2, sweep.description).Bind(3, sweep.canonical_spec);
  insert.Bind(4, sweep.spec_hash).Bind(5, sweep.source_name).Bind(6, sweep.source_text);
  insert.Bind(7, sweep.coordinator_build).Bind(8, sweep.max_attempts);
  insert.Bind(9, sweep.max_lost_leases).Bind(10, sweep.max_concurrent).Bind(11, now_ms);
  RETURN_IF_ERROR(insert.Run());
  const int64_t sweep_id = db.LastInsertRowId();
  ASSIGN_OR_RETURN(Statement job_insert, Statement::Prepare(db, R"sql(
INSERT INTO jobs(sweep_id, ordinal, method, seed, variant, options_json, episodes_expected, state,
               kind, payload)
VALUES(?, ?, ?, ?, ?, ?, ?, 'queued', ?, ?))sql"));
  for (size_t i = 0; i < sweep.jobs.size(); ++i) {
    const NewJob& job = sweep.jobs[i];
    job_insert.Bind(1, sweep_id).Bind(2, static_cast<int64_t>(i)).Bind(3, job.method);
    job_insert.Bind(4, job.seed).Bind(5, job.variant).Bind(6, OptionsToJson(job.options));
    // Study jobs report no episodes; the column's CHECK wants >= 1 (read back as 0).
    job_insert.Bind(7, job.kind == JobKind::kStudy ? 1 : job.episodes_expected);
    job_insert.Bind(8, ToString(job.kind)).Bind(9, job.payload);
    RETURN_IF_ERROR(job_insert.Run());
    job_insert.Reset();
    RETURN_IF_ERROR(internal::WriteJobOptions(db, db.LastInsertRowId(), job.method, job.seed,
                                              job.variant));
  }
  RETURN_IF_ERROR(internal::CreateSweepView(db, sweep_id, sweep.name));
  *created = true;
  return AddEvent(db, now_ms, sweep_id, 0, 0, "sweep_submitted",
                  absl::StrCat(sweep.jobs.size(), " jobs, spec ", sweep.spec_hash));
}

}  // namespace

absl::StatusOr<std::unique_ptr<SqliteStore>> SqliteStore::Open(const std::string& path,
                                                               const SqliteStoreOptions& options) {
  std::string recorded;
  ASSIGN_OR_RETURN(const int lock_fd, TakeLock(path, &recorded));
  // From here on the lock must be released on every error.
  absl::StatusOr<std::unique_ptr<SqliteStore>> opened = [&]()
      -> absl::StatusOr<std::unique_ptr<SqliteStore>> {
    ASSIGN_OR_RETURN(Inspection inspection, InspectFile(path, options.busy_timeout_ms));
    const bool recorded_database = recorded.find("\ndatabase ") != std::string::npos;
    switch (inspection.kind) {
      case FileKind::kMissing:
        if (recorded_database && !options.init) {
          return absl::FailedPreconditionError(absl::StrCat(
              "database ", path, " is missing, but its lock file records that a coordinator used "
              "a database there (", recorded.substr(recorded.find("\ndatabase ") + 1,
                                                    recorded.size()),
              "); it was deleted or moved. Restore it (e.g. from a backup), or pass --init to "
              "start a new, empty database"));
        }
        break;
      case FileKind::kEmpty:
      case FileKind::kEmptySqlite:
        if (!options.init) {
          return absl::FailedPreconditionError(absl::StrCat(
              path, " is ", inspection.kind == FileKind::kEmpty ? "an empty (0-byte) file"
                                                                : "an SQLite database without tables",
              ", not a totalgrad database; pass --init to initialise it as a new one"));
        }
        break;
      case FileKind::kTotalgrad:
        break;
    }
    ASSIGN_OR_RETURN(Db writer, Db::Open(path, /*create=*/true, options.busy_timeout_ms));
    // WAL lets the reader connection (and backups) run while the writer
    // commits; FULL makes every commit survive power loss, which matters more
    // than write speed here (a trial costs CPU-hours, a commit a millisecond).
    RETURN_IF_ERROR(writer.Exec("PRAGMA journal_mode=WAL"));
    RETURN_IF_ERROR(writer.Exec("PRAGMA synchronous=FULL"));
    // OFF while the schema is created or migrated (a migration may rebuild a
    // referenced table; internal::Migrate checks every key itself), ON after.
    RETURN_IF_ERROR(writer.Exec("PRAGMA foreign_keys=OFF"));
    {
      ASSIGN_OR_RETURN(Statement mode, Statement::Prepare(writer, "PRAGMA journal_mode"));
      ASSIGN_OR_RETURN(bool row, mode.Step());
      if (!row || mode.ColumnText(0) != "wal") {
        return absl::FailedPreconditionError(
            absl::StrCat("sqlite: ", path, " cannot use WAL journaling (journal_mode is '",
                         row ? mode.ColumnText(0) : "", "'); is it on a network file system?"));
      }
    }
    if (options.check_integrity_on_open) {
      ASSIGN_OR_RETURN(Statement check, Statement::Prepare(writer, "PRAGMA quick_check"));
      ASSIGN_OR_RETURN(bool row, check.Step());
      if (!row || check.ColumnText(0) != "ok") {
        return absl::DataLossError(absl::StrCat("sqlite: ", path, " failed its integrity check: ",
                                                row ? check.ColumnText(0) : "no answer"));
      }
    }
    if (inspection.kind != FileKind::kTotalgrad) {
      RETURN_IF_ERROR(writer.Exec("BEGIN IMMEDIATE"));
      absl::Status created = writer.Exec(internal::SchemaText());
      if (created.ok()) created = Migrate(writer, 1);
      if (created.ok()) created = writer.Exec("COMMIT");
      if (!created.ok()) {
        (void)writer.Exec("ROLLBACK");
        return created;
      }
    } else if (inspection.version < kSchemaVersion) {
      // An older totalgrad database: first a copy of it as it is (an older
      // build refuses the migrated file, and a migration is a one-way step),
      // then the migration in one transaction (all or nothing).
      std::string backup = absl::StrCat(path, ".schema-v", inspection.version, "-backup");
      for (int n = 1; std::filesystem::exists(backup); ++n) {
        backup = absl::StrCat(path, ".schema-v", inspection.version, "-backup.", n);
      }
      absl::StatusOr<int64_t> copied = BackupFile(path, backup);
      if (!copied.ok()) {
        return absl::Status(copied.status().code(),
                            absl::StrCat(path, ": not migrating from schema version ",
                                         inspection.version, ": the backup copy failed: ",
                                         copied.status().message()));
      }
      RETURN_IF_ERROR(writer.Exec("BEGIN IMMEDIATE"));
      absl::Status migrated = Migrate(writer, inspection.version);
      if (migrated.ok()) migrated = writer.Exec("COMMIT");
      if (!migrated.ok()) {
        (void)writer.Exec("ROLLBACK");
        return absl::Status(migrated.code(),
                            absl::StrCat(path, ": migrating from schema version ",
                                         inspection.version, " to ", kSchemaVersion,
                                         " failed: ", migrated.message()));
      }
    }
    RETURN_IF_ERROR(writer.Exec("PRAGMA foreign_keys=ON"));
    if (options.max_page_count > 0) {
      RETURN_IF_ERROR(
          writer.Exec(absl::StrCat("PRAGMA max_page_count=", options.max_page_count)));
    }
    ASSIGN_OR_RETURN(Db reader, Db::Open(path, /*create=*/false, options.busy_timeout_ms));
    RETURN_IF_ERROR(reader.Exec("PRAGMA foreign_keys=ON"));
    struct stat st;
    if (::stat(path.c_str(), &st) != 0) {
      return absl::FailedPreconditionError(
          absl::StrCat("cannot stat ", path, " after opening it: ", ErrnoText(errno)));
    }
    RecordHolder(lock_fd, path, st.st_dev, st.st_ino);
    return std::unique_ptr<SqliteStore>(new SqliteStore(path, options, std::move(writer),
                                                        std::move(reader), lock_fd, st.st_dev,
                                                        st.st_ino));
  }();
  if (!opened.ok()) ::close(lock_fd);
  return opened;
}

absl::StatusOr<std::unique_ptr<SqliteStore>> SqliteStore::OpenReadOnly(const std::string& path) {
  const SqliteStoreOptions options;
  ASSIGN_OR_RETURN(Inspection inspection, InspectFile(path, options.busy_timeout_ms));
  if (inspection.kind != FileKind::kTotalgrad) {
    return absl::FailedPreconditionError(absl::StrCat(
        path, inspection.kind == FileKind::kMissing ? " does not exist"
                                                     : " is not a totalgrad database",
        " (nothing to read)"));
  }
  if (inspection.version != kSchemaVersion) {
    return absl::FailedPreconditionError(absl::StrCat(
        path, " has schema version ", inspection.version, "; this build reads version ",
        kSchemaVersion,
        inspection.version < kSchemaVersion
            ? ": start a coordinator of this build on it once (it migrates the file, keeping a "
              "copy of the old one), or read it with the build that wrote it"
            : ": use a newer build"));
  }
  ASSIGN_OR_RETURN(Db writer, Db::OpenReadOnly(path, options.busy_timeout_ms));
  ASSIGN_OR_RETURN(Db reader, Db::OpenReadOnly(path, options.busy_timeout_ms));
  struct stat st;
  if (::stat(path.c_str(), &st) != 0) {
    return absl::FailedPreconditionError(
        absl::StrCat("cannot stat ", path, " after opening it: ", ErrnoText(errno)));
  }
  return std::unique_ptr<SqliteStore>(new SqliteStore(path, options, std::move(writer),
                                                      std::move(reader), /*lock_fd=*/-1,
                                                      st.st_dev, st.st_ino));
}

absl::StatusOr<int64_t> SqliteStore::BackupFile(const std::string& path, const std::string& target) {
  const int busy_timeout_ms = SqliteStoreOptions{}.busy_timeout_ms;
  ASSIGN_OR_RETURN(Inspection inspection, InspectFile(path, busy_timeout_ms));
  if (inspection.kind != FileKind::kTotalgrad) {
    return absl::FailedPreconditionError(
        absl::StrCat(path, " is not a totalgrad database (missing or empty); nothing to back up"));
  }
  ASSIGN_OR_RETURN(Db source, Db::OpenReadOnly(path, busy_timeout_ms));
  return CopyDatabase(source, target, busy_timeout_ms);
}

SqliteStore::SqliteStore(std::string path, SqliteStoreOptions options, Db writer, Db reader,
                         int lock_fd, uint64_t device, uint64_t inode)
    : path_(std::move(path)),
      options_(options),
      lock_fd_(lock_fd),
      device_(device),
      inode_(inode),
      writer_(std::move(writer)),
      reader_(std::move(reader)) {}

SqliteStore::~SqliteStore() {
  {
    std::lock_guard<std::mutex> lock(write_mutex_);
    // Fold the WAL back into the main file so a copied file is complete
    // (not into a file that replaced ours; never from a read-only view).
    if (lock_fd_ >= 0 && file_error_.ok() && CheckFileIdentityLocked().ok()) {
      (void)writer_.Exec("PRAGMA wal_checkpoint(TRUNCATE)");
    }
    writer_ = Db();
  }
  {
    std::lock_guard<std::mutex> lock(read_mutex_);
    reader_ = Db();
  }
  if (lock_fd_ >= 0) ::close(lock_fd_);  // releases the lock last, after both connections closed
}

absl::Status SqliteStore::CheckFileIdentityLocked() {
  if (!file_error_.ok()) return file_error_;
  struct stat st;
  std::string problem;
  if (::stat(path_.c_str(), &st) != 0) {
    problem = absl::StrCat("was deleted (", ErrnoText(errno), ")");
  } else if (st.st_dev != device_ || st.st_ino != inode_) {
    problem = absl::StrCat("was replaced by another file (device:inode ", device_, ":", inode_,
                           " when opened, now ", st.st_dev, ":", st.st_ino, ")");
  }
  if (problem.empty()) return absl::OkStatus();
  file_error_ = absl::UnavailableError(absl::StrCat(
      "database file ", path_, " ", problem,
      " while the coordinator was running; nothing is acknowledged any more (it would be lost "
      "with the old file). Restore the file and restart the coordinator"));
  return file_error_;
}

absl::Status SqliteStore::CheckWritable() {
  std::lock_guard<std::mutex> lock(write_mutex_);
  RETURN_IF_ERROR(CheckFileIdentityLocked());
  const int64_t now = SteadyMs();
  constexpr int64_t kProbeIntervalMs = 5000;
  if (last_write_error_.ok() && now - last_commit_ms_ < kProbeIntervalMs) return absl::OkStatus();
  if (!last_write_error_.ok() && now - last_failure_or_probe_ms_ < kProbeIntervalMs) {
    return absl::UnavailableError(
        absl::StrCat("the last database commit failed: ", last_write_error_.message()));
  }
  // Find out with a commit of our own.
  last_failure_or_probe_ms_ = now;
  absl::Status probe = writer_.Exec("BEGIN IMMEDIATE");
  if (probe.ok()) {
    probe = [&]() -> absl::Status {
      ASSIGN_OR_RETURN(Statement upsert,
                       Statement::Prepare(writer_, "INSERT INTO meta(key, value) VALUES('health_probe', ?) "
                                                   "ON CONFLICT(key) DO UPDATE SET value = excluded.value"));
      upsert.Bind(1, std::to_string(now));
      RETURN_IF_ERROR(upsert.Run());
      return writer_.Exec("COMMIT");
    }();
    if (!probe.ok()) (void)writer_.Exec("ROLLBACK");
  }
  if (!probe.ok()) {
    last_write_error_ = probe;
    return absl::UnavailableError(absl::StrCat("a probe commit failed: ", probe.message()));
  }
  last_write_error_ = absl::OkStatus();
  last_commit_ms_ = now;
  return absl::OkStatus();
}

absl::StatusOr<std::string> SqliteStore::DescribeSettings() {
  std::lock_guard<std::mutex> lock(write_mutex_);
  std::string description;
  for (const char* pragma : {"journal_mode", "synchronous", "foreign_keys", "busy_timeout"}) {
    ASSIGN_OR_RETURN(Statement query, Statement::Prepare(writer_, absl::StrCat("PRAGMA ", pragma)));
    ASSIGN_OR_RETURN(bool row, query.Step());
    absl::StrAppend(&description, description.empty() ? "" : " ", pragma, "=",
                    row ? query.ColumnText(0) : "?");
  }
  return description;
}

absl::Status SqliteStore::Ping() {
  std::lock_guard<std::mutex> lock(read_mutex_);
  ASSIGN_OR_RETURN(Statement query,
                   Statement::Prepare(reader_, "SELECT COUNT(*) FROM sqlite_master"));
  ASSIGN_OR_RETURN(bool row, query.Step());
  if (!row) return absl::InternalError("SELECT COUNT(*) FROM sqlite_master returned no row");
  return absl::OkStatus();
}

absl::Status SqliteStore::InWriteTransaction(const std::function<absl::Status(Db&)>& body) {
  if (lock_fd_ < 0) {
    return absl::FailedPreconditionError(
        absl::StrCat(path_, " is open read-only here; writes go through its coordinator"));
  }
  std::lock_guard<std::mutex> lock(write_mutex_);
  RETURN_IF_ERROR(CheckFileIdentityLocked());
  // IMMEDIATE takes the write lock up front: a deferred transaction that reads
  // then writes can fail with SQLITE_BUSY without the busy handler being used.
  absl::Status status = writer_.Exec("BEGIN IMMEDIATE");
  if (status.ok()) {
    status = body(writer_);
    if (status.ok()) status = writer_.Exec("COMMIT");
    if (!status.ok()) {
      (void)writer_.Exec("ROLLBACK");  // fails harmlessly if COMMIT already ended it
    }
  }
  if (status.ok()) {
    last_write_error_ = absl::OkStatus();
    last_commit_ms_ = SteadyMs();
  } else if (IsDatabaseFailure(status)) {
    last_write_error_ = status;
    last_failure_or_probe_ms_ = SteadyMs();
  }
  return status;
}

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

absl::Status SqliteStore::StartAttempt(const LeaseKey& key, const WorkerIdentity& worker,
                                       int64_t now_ms, int64_t lease_expires_ms) {
  return InWriteTransaction([&](Db& db) -> absl::Status {
    ASSIGN_OR_RETURN(Statement update, Statement::Prepare(db, R"sql(
UPDATE jobs SET state = 'running', attempts = ?
WHERE id = ? AND state = 'queued' AND attempts = ?)sql"));
    update.Bind(1, key.attempt).Bind(2, key.job_id).Bind(3, key.attempt - 1);
    RETURN_IF_ERROR(update.Run());
    if (db.Changes() != 1) {
      return absl::FailedPreconditionError(absl::StrCat(
          "job ", key.job_id, " is not queued at attempt ", key.attempt - 1));
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
  });
}

absl::StatusOr<int> SqliteStore::StoreEpisodes(const LeaseKey& key, const std::string& worker_id,
                                               const std::vector<Episode>& episodes,
                                               int64_t now_ms,
                                               std::optional<int64_t> lease_expires_ms) {
  int stored = 0;
  const absl::Status status = InWriteTransaction([&](Db& db) -> absl::Status {
    ASSIGN_OR_RETURN(OpenAttempt attempt, LoadAttempt(db, key));
    RETURN_IF_ERROR(CheckOpen(key, attempt, worker_id));
    RETURN_IF_ERROR(InsertEpisodes(db, key, attempt.episodes_expected, episodes, now_ms));
    if (lease_expires_ms.has_value()) {
      ASSIGN_OR_RETURN(Statement extend,
                       Statement::Prepare(db, "UPDATE attempts SET lease_expires_ms = ? "
                                              "WHERE job_id = ? AND attempt = ?"));
      extend.Bind(1, *lease_expires_ms).Bind(2, key.job_id).Bind(3, key.attempt);
      RETURN_IF_ERROR(extend.Run());
    }
    ASSIGN_OR_RETURN(Statement count,
                     Statement::Prepare(db, "SELECT COUNT(*) FROM episodes "
                                            "WHERE job_id = ? AND attempt = ?"));
    count.Bind(1, key.job_id).Bind(2, key.attempt);
    ASSIGN_OR_RETURN(bool row, count.Step());
    stored = row ? static_cast<int>(count.ColumnInt(0)) : 0;
    return absl::OkStatus();
  });
  if (!status.ok()) return status;
  return stored;
}

absl::StatusOr<int> SqliteStore::StoreStudyRows(const LeaseKey& key, const std::string& worker_id,
                                                const StudyRows& rows, int64_t now_ms,
                                                std::optional<int64_t> lease_expires_ms) {
  int stored = 0;
  const absl::Status status = InWriteTransaction([&](Db& db) -> absl::Status {
    ASSIGN_OR_RETURN(OpenAttempt attempt, LoadAttempt(db, key));
    RETURN_IF_ERROR(CheckOpen(key, attempt, worker_id));
    RETURN_IF_ERROR(InsertStudyRows(db, key, attempt.kind, rows, now_ms));
    if (lease_expires_ms.has_value()) {
      ASSIGN_OR_RETURN(Statement extend,
                       Statement::Prepare(db, "UPDATE attempts SET lease_expires_ms = ? "
                                              "WHERE job_id = ? AND attempt = ?"));
      extend.Bind(1, *lease_expires_ms).Bind(2, key.job_id).Bind(3, key.attempt);
      RETURN_IF_ERROR(extend.Run());
    }
    ASSIGN_OR_RETURN(stored, CountStudyRows(db, key));
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

absl::StatusOr<EndOutcome> SqliteStore::EndAttempt(const AttemptEnd& end) {
  if (end.attempt_state == AttemptState::kRunning) {
    return absl::InvalidArgumentError("EndAttempt needs a final attempt state, not running");
  }
  EndOutcome outcome = EndOutcome::kApplied;
  const absl::Status status = InWriteTransaction([&](Db& db) -> absl::Status {
    const LeaseKey& key = end.key;
    ASSIGN_OR_RETURN(OpenAttempt attempt, LoadAttempt(db, key));
    if (attempt.state == end.attempt_state && attempt.worker_id == end.worker_id) {
      outcome = EndOutcome::kAlreadyEnded;  // a repeated call: nothing to do
      return absl::OkStatus();
    }
    RETURN_IF_ERROR(CheckOpen(key, attempt, end.worker_id));
    RETURN_IF_ERROR(InsertEpisodes(db, key, attempt.episodes_expected, end.episodes, end.now_ms));
    RETURN_IF_ERROR(InsertStudyRows(db, key, attempt.kind, end.study, end.now_ms));
    if (end.checkpoint) RETURN_IF_ERROR(UpsertCheckpoint(db, key, attempt, *end.checkpoint, end.now_ms));
    const bool study_totals = end.study_cells_total != 0 || end.study_references_total != 0;
    if (end.attempt_state == AttemptState::kCompleted && attempt.kind == JobKind::kStudy) {
      if (end.study_cells_total < 1 || end.study_references_total < 1) {
        return absl::InvalidArgumentError(absl::StrCat(
            "completion of study job ", key.job_id, " reports ", end.study_cells_total,
            " cells and ", end.study_references_total,
            " references; a study has at least one of each"));
      }
      for (const auto& [table, total] :
           {std::pair<absl::string_view, int>{"study_cells", end.study_cells_total},
            std::pair<absl::string_view, int>{"study_references", end.study_references_total}}) {
        ASSIGN_OR_RETURN(std::vector<int> missing, MissingStudyRows(db, key, table, total));
        if (!missing.empty()) {
          return absl::FailedPreconditionError(absl::StrCat(
              "cannot complete job ", key.job_id, " attempt ", key.attempt, ": ", table, " rows ",
              absl::StrJoin(missing, ","), " of 0..", total - 1, " are not stored"));
        }
      }
    } else if (end.attempt_state == AttemptState::kCompleted && study_totals) {
      return absl::InvalidArgumentError(absl::StrCat(
          "job ", key.job_id, " is a trial job; it completes with episodes, not study rows"));
    } else if (end.attempt_state == AttemptState::kCompleted) {
      // The job's own expected count decides, never the worker's: a
      // completion reporting fewer episodes would count a trial with episodes
      // missing (docs/results_schema.md promises every episode 0..expected-1).
      if (end.episodes_total != attempt.episodes_expected) {
        return absl::InvalidArgumentError(absl::StrCat(
            "completion of job ", key.job_id, " attempt ", key.attempt, " reports ",
            end.episodes_total, " episodes; the job expects ", attempt.episodes_expected,
            " (episodes 0..", attempt.episodes_expected - 1, ")"));
      }
      ASSIGN_OR_RETURN(Statement present,
                       Statement::Prepare(db, "SELECT episode FROM episodes WHERE job_id = ? "
                                              "AND attempt = ? AND episode < ?"));
      present.Bind(1, key.job_id).Bind(2, key.attempt).Bind(3, attempt.episodes_expected);
      std::set<int> have;
      while (true) {
        ASSIGN_OR_RETURN(bool row, present.Step());
        if (!row) break;
        have.insert(static_cast<int>(present.ColumnInt(0)));
      }
      std::vector<int> missing;
      for (int e = 0; e < attempt.episodes_expected; ++e) {
        if (!have.count(e)) missing.push_back(e);
      }
      if (!missing.empty()) {
        return absl::FailedPreconditionError(absl::StrCat(
            "cannot complete job ", key.job_id, " attempt ", key.attempt, ": episodes ",
            absl::StrJoin(missing, ","), " of 0..", attempt.episodes_expected - 1,
            " are not stored"));
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
  });
  if (!status.ok()) return status;
  return outcome;
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

absl::Status SqliteStore::TouchWorker(const WorkerIdentity& worker, int64_t now_ms) {
  return InWriteTransaction([&](Db& db) -> absl::Status {
    ASSIGN_OR_RETURN(Statement upsert, Statement::Prepare(db, R"sql(
INSERT INTO workers(worker_id, host, build, slots, first_seen_ms, last_seen_ms)
VALUES(?, ?, ?, ?, ?, ?)
ON CONFLICT(worker_id) DO UPDATE SET host = excluded.host, build = excluded.build,
    slots = excluded.slots, last_seen_ms = excluded.last_seen_ms)sql"));
    upsert.Bind(1, worker.worker_id).Bind(2, worker.host).Bind(3, worker.build);
    upsert.Bind(4, worker.slots).Bind(5, now_ms).Bind(6, now_ms);
    return upsert.Run();
  });
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

// ---- reads ----

absl::StatusOr<SweepRecord> SqliteStore::GetSweep(const std::string& name) {
  std::lock_guard<std::mutex> lock(read_mutex_);
  return LoadSweep(reader_, name);
}

absl::StatusOr<std::vector<SweepRecord>> SqliteStore::ListSweeps() {
  std::lock_guard<std::mutex> lock(read_mutex_);
  RETURN_IF_ERROR(reader_.Exec("BEGIN"));  // one snapshot for the whole list
  std::vector<SweepRecord> sweeps;
  absl::Status status = [&]() -> absl::Status {
    ASSIGN_OR_RETURN(Statement query,
                     Statement::Prepare(reader_, absl::StrCat("SELECT ", kSweepColumns,
                                                              " FROM sweeps s ORDER BY s.id DESC")));
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
  std::lock_guard<std::mutex> lock(read_mutex_);
  return LoadJob(reader_, job_id);
}

absl::StatusOr<std::vector<JobRecord>> SqliteStore::ListJobs(const JobFilter& filter) {
  std::lock_guard<std::mutex> lock(read_mutex_);
  // The state filter is one bound parameter: a list ",queued,,running," that
  // each job's state is looked up in with instr().
  std::string states;
  for (JobState s : filter.states) absl::StrAppend(&states, ",", ToString(s), ",");
  ASSIGN_OR_RETURN(Statement query, Statement::Prepare(reader_, absl::StrCat(kJobSelect, R"sql(
WHERE (? = '' OR s.name = ?) AND (? = '' OR instr(?, ',' || j.state || ',') > 0) AND j.id > ?
ORDER BY j.id LIMIT ?)sql")));
  query.Bind(1, filter.sweep_name).Bind(2, filter.sweep_name).Bind(3, states).Bind(4, states);
  query.Bind(5, filter.after_job_id).Bind(6, filter.limit);
  std::vector<JobRecord> jobs;
  while (true) {
    ASSIGN_OR_RETURN(bool row, query.Step());
    if (!row) break;
    jobs.push_back(ReadJobRow(query));
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

absl::StatusOr<std::vector<AttemptRecord>> SqliteStore::ListAttempts(int64_t job_id) {
  std::lock_guard<std::mutex> lock(read_mutex_);
  ASSIGN_OR_RETURN(Statement query, Statement::Prepare(reader_, R"sql(
SELECT a.attempt, a.state, a.worker_id, a.worker_host, a.worker_build, a.started_ms,
       COALESCE(a.ended_ms, 0), a.lease_expires_ms, a.error,
       (SELECT COUNT(*) FROM episodes e WHERE e.job_id = a.job_id AND e.attempt = a.attempt),
       COALESCE((SELECT c.episode FROM checkpoints c
                 WHERE c.job_id = a.job_id AND c.attempt = a.attempt), -1)
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
    attempts.push_back(std::move(a));
  }
  return attempts;
}

absl::StatusOr<std::vector<EventRecord>> SqliteStore::ListEvents(int64_t job_id) {
  std::lock_guard<std::mutex> lock(read_mutex_);
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
  std::lock_guard<std::mutex> lock(read_mutex_);
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

absl::StatusOr<std::vector<ClaimCandidate>> SqliteStore::ListClaimCandidates(int limit) {
  std::lock_guard<std::mutex> lock(read_mutex_);
  ASSIGN_OR_RETURN(Statement query, Statement::Prepare(reader_, R"sql(
SELECT j.id, j.attempts, s.id, s.max_concurrent,
       (SELECT COUNT(*) FROM jobs r WHERE r.sweep_id = s.id AND r.state = 'running'), j.kind
FROM jobs j JOIN sweeps s ON s.id = j.sweep_id
WHERE j.state = 'queued' AND s.state = 'running'
ORDER BY s.id, j.ordinal LIMIT ?)sql"));
  query.Bind(1, limit);
  std::vector<ClaimCandidate> candidates;
  while (true) {
    ASSIGN_OR_RETURN(bool row, query.Step());
    if (!row) break;
    ClaimCandidate c;
    c.job_id = query.ColumnInt(0);
    c.kind = ParseJobKind(query.ColumnText(5)).value_or(JobKind::kTrial);
    c.attempts = static_cast<int>(query.ColumnInt(1));
    c.sweep_id = query.ColumnInt(2);
    c.max_concurrent = static_cast<int>(query.ColumnInt(3));
    c.sweep_running = static_cast<int>(query.ColumnInt(4));
    candidates.push_back(c);
  }
  return candidates;
}

absl::StatusOr<std::vector<LeaseKey>> SqliteStore::ListExpiredLeases(int64_t now_ms) {
  std::lock_guard<std::mutex> lock(read_mutex_);
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
  std::lock_guard<std::mutex> lock(read_mutex_);
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
  std::lock_guard<std::mutex> lock(read_mutex_);
  ASSIGN_OR_RETURN(Statement query,
                   Statement::Prepare(reader_, absl::StrCat(kWorkerSelect,
                                                            " WHERE w.worker_id = ?")));
  query.Bind(1, worker_id);
  ASSIGN_OR_RETURN(bool row, query.Step());
  if (!row) return absl::NotFoundError(absl::StrCat("no worker with id '", worker_id, "'"));
  return ReadWorkerRow(query);
}

absl::StatusOr<std::vector<TrialResultRecord>> SqliteStore::ListTrialResults(
    const std::string& sweep_name) {
  std::lock_guard<std::mutex> lock(read_mutex_);
  ASSIGN_OR_RETURN(Statement check, Statement::Prepare(reader_, "SELECT id FROM sweeps WHERE name = ?"));
  check.Bind(1, sweep_name);
  ASSIGN_OR_RETURN(bool found, check.Step());
  if (!found) return absl::NotFoundError(absl::StrCat("no sweep named '", sweep_name, "'"));
  const int64_t sweep_id = check.ColumnInt(0);
  ASSIGN_OR_RETURN(Statement query, Statement::Prepare(reader_, R"sql(
SELECT j.id, j.method, j.seed, j.variant, j.completed_attempt, j.success, j.final_eval_cost,
       (SELECT COUNT(*) FROM episodes e WHERE e.job_id = j.id AND e.attempt = j.completed_attempt)
FROM jobs j WHERE j.sweep_id = ? AND j.state = 'completed' AND j.kind = 'trial'
ORDER BY j.ordinal)sql"));
  query.Bind(1, sweep_id);
  std::vector<TrialResultRecord> results;
  while (true) {
    ASSIGN_OR_RETURN(bool row, query.Step());
    if (!row) break;
    TrialResultRecord r;
    r.job_id = query.ColumnInt(0);
    r.method = query.ColumnText(1);
    r.seed = query.ColumnText(2);
    r.variant = query.ColumnText(3);
    r.attempt = static_cast<int>(query.ColumnInt(4));
    r.success = query.ColumnInt(5) != 0;
    r.final_eval_cost = query.ColumnDouble(6);
    r.episodes = static_cast<int>(query.ColumnInt(7));
    results.push_back(std::move(r));
  }
  return results;
}

absl::Status SqliteStore::ExportEpisodes(
    const std::string& sweep_name, bool all_attempts, int batch_size,
    const std::function<absl::Status(std::vector<EpisodeRowRecord>)>& sink) {
  // A connection of its own: a long export holds one read snapshot without
  // blocking the other readers.
  ASSIGN_OR_RETURN(Db db, Db::Open(path_, /*create=*/false, options_.busy_timeout_ms));
  RETURN_IF_ERROR(db.Exec("BEGIN"));
  ASSIGN_OR_RETURN(Statement check, Statement::Prepare(db, "SELECT id FROM sweeps WHERE name = ?"));
  check.Bind(1, sweep_name);
  ASSIGN_OR_RETURN(bool found, check.Step());
  if (!found) return absl::NotFoundError(absl::StrCat("no sweep named '", sweep_name, "'"));
  const int64_t sweep_id = check.ColumnInt(0);
  ASSIGN_OR_RETURN(Statement query, Statement::Prepare(db, R"sql(
SELECT e.job_id, e.attempt, j.method, j.seed, j.variant, e.episode, e.real_cost, e.eval_cost_mean,
       e.eval_cost_std, e.predicted_cost, e.optimisation_seconds, e.details_json, e.reported_ms,
       COALESCE(j.completed_attempt, 0) = e.attempt, e.cpu_seconds
FROM episodes e JOIN jobs j ON j.id = e.job_id
WHERE j.sweep_id = ? AND (? OR e.attempt = COALESCE(j.completed_attempt, j.attempts))
ORDER BY e.job_id, e.attempt, e.episode)sql"));
  query.Bind(1, sweep_id).Bind(2, all_attempts ? 1 : 0);
  std::vector<EpisodeRowRecord> batch;
  while (true) {
    ASSIGN_OR_RETURN(bool row, query.Step());
    if (!row) break;
    EpisodeRowRecord r;
    r.job_id = query.ColumnInt(0);
    r.attempt = static_cast<int>(query.ColumnInt(1));
    r.method = query.ColumnText(2);
    r.seed = query.ColumnText(3);
    r.variant = query.ColumnText(4);
    r.episode.episode = static_cast<int>(query.ColumnInt(5));
    r.episode.real_cost = query.ColumnDouble(6);
    r.episode.eval_cost_mean = query.ColumnDouble(7);
    r.episode.eval_cost_std = query.ColumnDouble(8);
    r.episode.predicted_cost = query.ColumnDouble(9);
    r.episode.optimisation_seconds = query.ColumnDouble(10);
    r.episode.details_json = query.ColumnText(11);
    r.reported_ms = query.ColumnInt(12);
    r.final_attempt = query.ColumnInt(13) != 0;
    r.episode.cpu_seconds = query.ColumnDouble(14);
    batch.push_back(std::move(r));
    if (static_cast<int>(batch.size()) >= batch_size) {
      RETURN_IF_ERROR(sink(std::move(batch)));
      batch.clear();
    }
  }
  if (!batch.empty()) RETURN_IF_ERROR(sink(std::move(batch)));
  return absl::OkStatus();
}

absl::Status SqliteStore::ListStudyRows(const std::string& sweep_name, bool all_attempts,
                                        std::vector<StudyCellRecord>* cells,
                                        std::vector<StudyReferenceRecord>* references) {
  std::lock_guard<std::mutex> lock(read_mutex_);
  RETURN_IF_ERROR(reader_.Exec("BEGIN"));  // one snapshot for cells and references
  const absl::Status status = [&]() -> absl::Status {
    ASSIGN_OR_RETURN(Statement check,
                     Statement::Prepare(reader_, "SELECT id FROM sweeps WHERE name = ?"));
    check.Bind(1, sweep_name);
    ASSIGN_OR_RETURN(bool found, check.Step());
    if (!found) return absl::NotFoundError(absl::StrCat("no sweep named '", sweep_name, "'"));
    const int64_t sweep_id = check.ColumnInt(0);
    ASSIGN_OR_RETURN(Statement query, Statement::Prepare(reader_, R"sql(
SELECT c.job_id, c.attempt, j.variant, COALESCE(j.completed_attempt, 0) = c.attempt, c.idx,
       c.estimator, c.method, c.particles, c.horizon, c.replicates, c.nonfinite, c.errors,
       c.time_min_s, c.time_median_s, c.rel_rmse, c.rel_bias, c.rel_bias_noise, c.total_variance,
       c.cos_mean, c.objective_mean, c.ess_mean, c.ess_min, c.k_lr_mean, c.reference_agrees,
       c.reference_floor, c.budget_hit, c.omitted, c.note, c.error, c.omission_reason,
       c.k_lr_per_step_json
FROM study_cells c JOIN jobs j ON j.id = c.job_id
WHERE j.sweep_id = ? AND (? OR c.attempt = COALESCE(j.completed_attempt, j.attempts))
ORDER BY c.job_id, c.attempt, c.idx)sql"));
    query.Bind(1, sweep_id).Bind(2, all_attempts ? 1 : 0);
    while (true) {
      ASSIGN_OR_RETURN(bool row, query.Step());
      if (!row) break;
      StudyCellRecord r;
      ReadStudyRowHeader(query, &r);
      StudyCell& c = r.cell;
      c.index = static_cast<int>(query.ColumnInt(4));
      c.estimator = query.ColumnText(5);
      c.method = query.ColumnText(6);
      c.particles = static_cast<int>(query.ColumnInt(7));
      c.horizon = static_cast<int>(query.ColumnInt(8));
      c.replicates = static_cast<int>(query.ColumnInt(9));
      c.nonfinite = static_cast<int>(query.ColumnInt(10));
      c.errors = static_cast<int>(query.ColumnInt(11));
      double* const doubles[] = {&c.time_min_s, &c.time_median_s, &c.rel_rmse, &c.rel_bias,
                                 &c.rel_bias_noise, &c.total_variance, &c.cos_mean,
                                 &c.objective_mean, &c.ess_mean, &c.ess_min, &c.k_lr_mean};
      for (int i = 0; i < 11; ++i) *doubles[i] = query.ColumnDouble(12 + i);
      c.reference_agrees = query.ColumnInt(23) != 0;
      c.reference_floor = query.ColumnDouble(24);
      c.budget_hit = query.ColumnInt(25) != 0;
      c.omitted = query.ColumnInt(26) != 0;
      c.note = query.ColumnText(27);
      c.error = query.ColumnText(28);
      c.omission_reason = query.ColumnText(29);
      c.k_lr_per_step = DoublesFromJson(query.ColumnText(30));
      cells->push_back(std::move(r));
    }
    ASSIGN_OR_RETURN(Statement refs, Statement::Prepare(reader_, R"sql(
SELECT r.job_id, r.attempt, j.variant, COALESCE(j.completed_attempt, 0) = r.attempt, r.idx,
       r.horizon, r.norm, r.relative_error, r.floor, r.objective, r.used_json, r.replicates_json,
       r.agreement_max_z, r.agreement_mean_z2, r.agree, r.seconds, r.note, r.gradient_json,
       r.standard_error_json
FROM study_references r JOIN jobs j ON j.id = r.job_id
WHERE j.sweep_id = ? AND (? OR r.attempt = COALESCE(j.completed_attempt, j.attempts))
ORDER BY r.job_id, r.attempt, r.idx)sql"));
    refs.Bind(1, sweep_id).Bind(2, all_attempts ? 1 : 0);
    while (true) {
      ASSIGN_OR_RETURN(bool row, refs.Step());
      if (!row) break;
      StudyReferenceRecord r;
      ReadStudyRowHeader(refs, &r);
      StudyReference& g = r.reference;
      g.index = static_cast<int>(refs.ColumnInt(4));
      g.horizon = static_cast<int>(refs.ColumnInt(5));
      g.norm = refs.ColumnDouble(6);
      g.relative_error = refs.ColumnDouble(7);
      g.floor = refs.ColumnDouble(8);
      g.objective = refs.ColumnDouble(9);
      const nlohmann::json used = nlohmann::json::parse(refs.ColumnText(10), nullptr, false);
      if (used.is_array()) {
        for (const auto& u : used) g.used.push_back(u.is_string() ? u.get<std::string>() : "");
      }
      const nlohmann::json reps = nlohmann::json::parse(refs.ColumnText(11), nullptr, false);
      if (reps.is_array()) {
        for (const auto& n : reps) g.replicates.push_back(n.is_number_integer() ? n.get<int>() : 0);
      }
      g.agreement_max_z = refs.ColumnDouble(12);
      g.agreement_mean_z2 = refs.ColumnDouble(13);
      g.agree = refs.ColumnInt(14) != 0;
      g.seconds = refs.ColumnDouble(15);
      g.note = refs.ColumnText(16);
      g.gradient = DoublesFromJson(refs.ColumnText(17));
      g.standard_error = DoublesFromJson(refs.ColumnText(18));
      references->push_back(std::move(r));
    }
    return absl::OkStatus();
  }();
  (void)reader_.Exec("COMMIT");
  return status;
}

absl::StatusOr<StoreCounts> SqliteStore::Counts() {
  std::lock_guard<std::mutex> lock(read_mutex_);
  ASSIGN_OR_RETURN(Statement query, Statement::Prepare(reader_, R"sql(
SELECT (SELECT COUNT(*) FROM sweeps),
       (SELECT COUNT(*) FROM jobs WHERE state = 'queued'),
       (SELECT COUNT(*) FROM jobs WHERE state = 'running'))sql"));
  ASSIGN_OR_RETURN(bool row, query.Step());
  StoreCounts counts;
  if (row) {
    counts.sweeps = static_cast<int>(query.ColumnInt(0));
    counts.jobs_queued = static_cast<int>(query.ColumnInt(1));
    counts.jobs_running = static_cast<int>(query.ColumnInt(2));
  }
  return counts;
}

absl::StatusOr<int64_t> SqliteStore::Backup(const std::string& path) {
  ASSIGN_OR_RETURN(Db source, Db::OpenReadOnly(path_, options_.busy_timeout_ms));
  return CopyDatabase(source, path, options_.busy_timeout_ms);
}

absl::StatusOr<ImportResult> SqliteStore::ImportJobs(const std::optional<NewSweep>& create,
                                                    const std::string& sweep_name,
                                                    const std::vector<ImportedJob>& jobs,
                                                    const std::string& source, int64_t now_ms) {
  ImportResult result;
  const absl::Status status = InWriteTransaction([&](Db& db) -> absl::Status {
    result = ImportResult();
    if (create.has_value()) {
      RETURN_IF_ERROR(InsertSweep(db, *create, now_ms, &result.sweep_created));
    }
    ASSIGN_OR_RETURN(Statement sweep_query,
                     Statement::Prepare(db, "SELECT id FROM sweeps WHERE name = ?"));
    sweep_query.Bind(1, sweep_name);
    ASSIGN_OR_RETURN(bool found, sweep_query.Step());
    if (!found) return absl::NotFoundError(absl::StrCat("no sweep named '", sweep_name, "'"));
    const int64_t sweep_id = sweep_query.ColumnInt(0);
    ASSIGN_OR_RETURN(Statement job_query, Statement::Prepare(db, R"sql(
SELECT id, state, attempts, episodes_expected FROM jobs
WHERE sweep_id = ? AND kind = ? AND method = ? AND seed = ? AND variant = ?)sql"));
    ASSIGN_OR_RETURN(Statement attempt_insert, Statement::Prepare(db, R"sql(
INSERT INTO attempts(job_id, attempt, state, worker_id, worker_host, worker_build, started_ms,
                     lease_expires_ms, ended_ms, error)
VALUES(?, ?, ?, ?, ?, ?, ?, ?, ?, ?))sql"));
    ASSIGN_OR_RETURN(Statement episode_insert, Statement::Prepare(db, R"sql(
INSERT INTO episodes(job_id, attempt, episode, real_cost, eval_cost_mean, eval_cost_std,
                     predicted_cost, optimisation_seconds, details_json, reported_ms, cpu_seconds)
VALUES(?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?))sql"));
    ASSIGN_OR_RETURN(Statement job_update, Statement::Prepare(db, R"sql(
UPDATE jobs SET state = 'completed', attempts = ?, completed_attempt = ?, success = ?,
                final_eval_cost = ?, failures = failures + ?, lost_leases = lost_leases + ?,
                last_error = ?
WHERE id = ?)sql"));
    for (const ImportedJob& job : jobs) {
      job_query.Bind(1, sweep_id).Bind(2, ToString(job.kind)).Bind(3, job.method);
      job_query.Bind(4, job.seed).Bind(5, job.variant);
      ASSIGN_OR_RETURN(bool match, job_query.Step());
      const int64_t job_id = match ? job_query.ColumnInt(0) : 0;
      const std::string state = match ? job_query.ColumnText(1) : "";
      const int attempts_here = match ? static_cast<int>(job_query.ColumnInt(2)) : 0;
      const int episodes_expected = match ? static_cast<int>(job_query.ColumnInt(3)) : 0;
      job_query.Reset();
      if (!match) {
        ++result.jobs_unknown;
        continue;
      }
      if (state == ToString(JobState::kCompleted)) {
        ++result.jobs_already_complete;
        continue;
      }
      if (job.state != JobState::kCompleted || job.completed_attempt <= 0) {
        ++result.jobs_not_completed;
        continue;
      }
      if (state == ToString(JobState::kRunning)) {
        ++result.jobs_running_here;
        continue;
      }
      int completed_here = 0;
      for (size_t i = 0; i < job.attempts.size(); ++i) {
        const ImportedAttempt& a = job.attempts[i];
        const int number = attempts_here + static_cast<int>(i) + 1;
        if (a.attempt == job.completed_attempt) completed_here = number;
        // An attempt that was still open where the archive was written ran
        // nowhere here: it arrives released.
        const AttemptState arrived =
            a.state == AttemptState::kRunning ? AttemptState::kReleased : a.state;
        attempt_insert.Bind(1, job_id).Bind(2, number).Bind(3, ToString(arrived));
        attempt_insert.Bind(4, a.worker_id).Bind(5, a.worker_host).Bind(6, a.worker_build);
        attempt_insert.Bind(7, a.started_ms).Bind(8, a.ended_ms > 0 ? a.ended_ms : a.started_ms);
        attempt_insert.Bind(9, a.ended_ms > 0 ? a.ended_ms : now_ms).Bind(10, a.error);
        RETURN_IF_ERROR(attempt_insert.Run());
        attempt_insert.Reset();
        for (const auto& [episode, reported_ms] : a.episodes) {
          if (episode.episode < 0 || episode.episode >= episodes_expected ||
              job.kind != JobKind::kTrial) {
            return absl::InvalidArgumentError(absl::StrCat(
                "archive: job ", job.method, " seed ", job.seed, " ", job.variant, " attempt ",
                a.attempt, ": episode ", episode.episode, " is out of range 0..",
                episodes_expected - 1));
          }
          episode_insert.Bind(1, job_id).Bind(2, number).Bind(3, episode.episode);
          episode_insert.Bind(4, episode.real_cost).Bind(5, episode.eval_cost_mean);
          episode_insert.Bind(6, episode.eval_cost_std).Bind(7, episode.predicted_cost);
          episode_insert.Bind(8, episode.optimisation_seconds).Bind(9, episode.details_json);
          episode_insert.Bind(10, reported_ms).Bind(11, episode.cpu_seconds);
          RETURN_IF_ERROR(episode_insert.Run());
          episode_insert.Reset();
          ++result.episodes_imported;
        }
        if (!a.study.empty()) {
          RETURN_IF_ERROR(InsertStudyRows(db, {job_id, number}, job.kind, a.study, now_ms));
          result.study_rows_imported += static_cast<int64_t>(a.study.size());
        }
      }
      if (completed_here == 0) {
        return absl::InvalidArgumentError(absl::StrCat(
            "archive: job ", job.method, " seed ", job.seed, " ", job.variant,
            " is completed by attempt ", job.completed_attempt, ", which the archive lacks"));
      }
      job_update.Bind(1, attempts_here + static_cast<int>(job.attempts.size()));
      job_update.Bind(2, completed_here).Bind(3, job.success ? 1 : 0);
      job_update.Bind(4, job.final_eval_cost).Bind(5, job.failures).Bind(6, job.lost_leases);
      job_update.Bind(7, job.last_error).Bind(8, job_id);
      RETURN_IF_ERROR(job_update.Run());
      job_update.Reset();
      RETURN_IF_ERROR(AddEvent(db, now_ms, sweep_id, job_id, completed_here, "imported",
                               absl::StrCat("completed attempt ", job.completed_attempt, " of ",
                                            source, " (now attempt ", completed_here, ")")));
      ++result.jobs_imported;
    }
    return AddEvent(db, now_ms, sweep_id, 0, 0, "sweep_imported",
                    absl::StrCat(source, ": ", result.jobs_imported, " jobs taken over, ",
                                 result.jobs_already_complete, " already complete here, ",
                                 result.jobs_not_completed, " not completed there"));
  });
  if (!status.ok()) return status;
  return result;
}

absl::StatusOr<int> SqliteStore::GrowSweep(const NewSweep& grown, int64_t now_ms) {
  int added = 0;
  const absl::Status status = InWriteTransaction([&](Db& db) -> absl::Status {
    added = 0;
    ASSIGN_OR_RETURN(Statement sweep_query,
                     Statement::Prepare(db, "SELECT id, spec_hash FROM sweeps WHERE name = ?"));
    sweep_query.Bind(1, grown.name);
    ASSIGN_OR_RETURN(bool found, sweep_query.Step());
    if (!found) return absl::NotFoundError(absl::StrCat("no sweep named '", grown.name, "'"));
    const int64_t sweep_id = sweep_query.ColumnInt(0);
    const std::string previous_hash = sweep_query.ColumnText(1);
    ASSIGN_OR_RETURN(Statement exists, Statement::Prepare(db, R"sql(
SELECT 1 FROM jobs WHERE sweep_id = ? AND kind = ? AND method = ? AND seed = ? AND variant = ?)sql"));
    ASSIGN_OR_RETURN(Statement last, Statement::Prepare(
        db, "SELECT COALESCE(MAX(ordinal), -1) FROM jobs WHERE sweep_id = ?"));
    last.Bind(1, sweep_id);
    ASSIGN_OR_RETURN(bool any, last.Step());
    int64_t ordinal = any ? last.ColumnInt(0) : -1;
    ASSIGN_OR_RETURN(Statement job_insert, Statement::Prepare(db, R"sql(
INSERT INTO jobs(sweep_id, ordinal, method, seed, variant, options_json, episodes_expected, state,
                 kind, payload)
VALUES(?, ?, ?, ?, ?, ?, ?, 'queued', ?, ?))sql"));
    for (const NewJob& job : grown.jobs) {
      exists.Bind(1, sweep_id).Bind(2, ToString(job.kind)).Bind(3, job.method);
      exists.Bind(4, job.seed).Bind(5, job.variant);
      ASSIGN_OR_RETURN(bool present, exists.Step());
      exists.Reset();
      if (present) continue;
      job_insert.Bind(1, sweep_id).Bind(2, ++ordinal).Bind(3, job.method).Bind(4, job.seed);
      job_insert.Bind(5, job.variant).Bind(6, OptionsToJson(job.options));
      job_insert.Bind(7, job.kind == JobKind::kStudy ? 1 : job.episodes_expected);
      job_insert.Bind(8, ToString(job.kind)).Bind(9, job.payload);
      RETURN_IF_ERROR(job_insert.Run());
      job_insert.Reset();
      RETURN_IF_ERROR(internal::WriteJobOptions(db, db.LastInsertRowId(), job.method, job.seed,
                                                job.variant));
      ++added;
    }
    ASSIGN_OR_RETURN(Statement update, Statement::Prepare(db, R"sql(
UPDATE sweeps SET canonical_spec = ?, spec_hash = ?, description = ?, source_name = ?,
                  source_text = ?
WHERE id = ?)sql"));
    update.Bind(1, grown.canonical_spec).Bind(2, grown.spec_hash).Bind(3, grown.description);
    update.Bind(4, grown.source_name).Bind(5, grown.source_text).Bind(6, sweep_id);
    RETURN_IF_ERROR(update.Run());
    RETURN_IF_ERROR(internal::CreateSweepView(db, sweep_id, grown.name));
    return AddEvent(db, now_ms, sweep_id, 0, 0, "sweep_grown",
                    absl::StrCat(added, " jobs added; spec ", previous_hash.substr(0, 12), " -> ",
                                 grown.spec_hash.substr(0, 12)));
  });
  if (!status.ok()) return status;
  return added;
}

}  // namespace totalgrad::storage
