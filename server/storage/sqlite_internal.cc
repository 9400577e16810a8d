// Row helpers shared by the SqliteStore's files (sqlite_internal.h).
#include "server/storage/sqlite_internal.h"

#include <algorithm>
#include <cmath>
#include <set>
#include <utility>

#include <nlohmann/json.hpp>

#include "absl/strings/numbers.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_join.h"
#include "runtime/status_macros.h"
#include "server/storage/service_records.h"
#include "server/storage/sqlite_records.h"
#include "server/storage/sqlite_schema.h"

namespace totalgrad::storage::internal {

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

std::string OptionsToJson(const OptionPairs& options) {
  nlohmann::json array = nlohmann::json::array();
  for (const auto& [key, value] : options) array.push_back({key, value});
  return array.dump();
}

OptionPairs OptionsFromJson(const std::string& text) {
  OptionPairs options;
  const nlohmann::json array = nlohmann::json::parse(text, nullptr, /*allow_exceptions=*/false);
  if (!array.is_array()) return options;
  for (const auto& pair : array) {
    if (pair.is_array() && pair.size() == 2 && pair[0].is_string() && pair[1].is_string()) {
      options.emplace_back(pair[0].get<std::string>(), pair[1].get<std::string>());
    }
  }
  return options;
}

OptionPairs WithJobValues(const OptionPairs& shared, const OptionPairs& job_values) {
  OptionPairs options = shared;
  for (auto& [key, value] : options) {
    for (const auto& [job_key, job_value] : job_values) {
      if (job_key == key) value = job_value;
    }
  }
  return options;
}

OptionPairs StoredJobOptions(const std::string& stored, JobKind kind, const std::string& method,
                             const std::string& seed, const std::string& variant,
                             const std::optional<std::string>& shared, SharedOptionsCache* cache) {
  if (!stored.empty() || kind != JobKind::kTrial || !shared) return OptionsFromJson(stored);
  SharedOptionsCache local;
  if (cache == nullptr) cache = &local;
  if (cache->text != *shared || cache->options.empty()) {
    cache->text = *shared;
    cache->options = OptionsFromJson(*shared);
  }
  return WithJobValues(cache->options, JobOptionPairs(method, seed, variant));
}

const char* JobOptionsJsonSql() {
  // json_each walks the shared list in its order (b.key is the index); the
  // ordered subquery keeps that order into json_group_array, and json()
  // keeps each pair an array rather than its text.
  return R"sql((CASE WHEN j.options_json = '' AND j.kind = 'trial' THEN
  (SELECT json_group_array(json(pair)) FROM
    (SELECT json_array(b.value ->> 0, COALESCE(o.value, b.value ->> 1)) AS pair
     FROM json_each((SELECT s2.trial_options_json FROM sweeps s2 WHERE s2.id = j.sweep_id)) b
     LEFT JOIN job_options o ON o.job_id = j.id AND o.key = b.value ->> 0
     ORDER BY b.key))
  ELSE j.options_json END))sql";
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


namespace {

// Where the store reads each field of a sweep summary from; the counts are
// computed by ReadSweepRow from the sweep's jobs.
const SqlView<SweepRecord>& SweepView() {
  static const SqlView<SweepRecord> view = MakeSqlView<SweepRecord>(
      {&SweepFields(), &SweepStoreOnlyFields()},
      {{"id", "s.id"},
       {"name", "s.name"},
       {"description", "s.description"},
       {"state", "s.state"},
       {"canonical_spec", "s.canonical_spec"},
       {"spec_hash", "s.spec_hash"},
       {"source_name", "s.source_name"},
       {"coordinator_build", "s.coordinator_build"},
       {"created_unix_ms", "s.created_ms"},
       {"max_attempts", "s.max_attempts"},
       {"max_lost_leases", "s.max_lost_leases"},
       {"max_concurrent", "s.max_concurrent"}},
      {"jobs_total", "jobs_queued", "jobs_running", "jobs_completed", "jobs_failed",
       "jobs_cancelled", "episodes_stored", "episodes_expected"});
  return view;
}

// Where the store reads each field of a job from: its row j, its sweep's s,
// or the rows of its latest attempt. episodes_expected is the column as
// stored; ReadJobRow applies the job kind's rule to it.
// A job's held_fraction: its completed attempt's last episode's (NULL
// unless completed).
constexpr char kHeldFractionSql[] =
    "(SELECT e.held_fraction FROM episodes e WHERE e.job_id = j.id AND "
    "e.attempt = j.completed_attempt ORDER BY e.episode DESC LIMIT 1)";

const SqlView<JobRecord>& JobView() {
  static const SqlView<JobRecord> view = MakeSqlView<JobRecord>(
      {&JobFields(), &JobStoreOnlyFields()},
      {{"job_id", "j.id"},
       {"sweep_name", "s.name"},
       {"kind", "j.kind"},
       {"ordinal", "j.ordinal"},
       {"method", "j.method"},
       {"seed", "j.seed"},
       {"variant", "j.variant"},
       {"options", "j.options_json"},  // '' for most trial jobs: ReadJobRow
       {"state", "j.state"},
       {"attempts", "j.attempts"},
       {"failures", "j.failures"},
       {"lost_leases", "j.lost_leases"},
       {"episodes_stored",
        "(SELECT COUNT(*) FROM episodes e WHERE e.job_id = j.id AND e.attempt = j.attempts)"},
       {"episodes_expected", "j.episodes_expected"},
       {"worker_id",
        "COALESCE((SELECT a.worker_id FROM attempts a WHERE a.job_id = j.id AND "
        "a.attempt = j.attempts AND a.state = 'running'), '')"},
       {"success", "COALESCE(j.success, 0)"},
       {"final_eval_cost", "j.final_eval_cost"},
       {"held_fraction", kHeldFractionSql},
       {"last_error", "j.last_error"},
       {"sweep_id", "j.sweep_id"},
       {"sweep_state", "s.state"},
       {"max_attempts", "s.max_attempts"},
       {"max_lost_leases", "s.max_lost_leases"},
       {"completed_attempt", "COALESCE(j.completed_attempt, 0)"},
       {"payload", "j.payload"}},
      {});
  return view;
}

}  // namespace

const std::string& SweepSelectSql() {
  static const std::string sql = absl::StrCat("SELECT ", SweepView().select_list, " FROM sweeps s");
  return sql;
}

absl::StatusOr<SweepRecord> ReadSweepRow(Db& db, const Statement& row) {
  SweepRecord sweep;
  ReadRecord(row, 0, SweepView().fields, &sweep);
  ASSIGN_OR_RETURN(Statement counts,
                   Statement::Prepare(db, "SELECT state, COUNT(*), SUM(episodes_expected), kind "
                                          "FROM jobs WHERE sweep_id = ? GROUP BY state, kind"));
  counts.Bind(1, sweep.id);
  while (true) {
    ASSIGN_OR_RETURN(bool more, counts.Step());
    if (!more) break;
    const int n = static_cast<int>(counts.ColumnInt(1));
    sweep.jobs_total += n;
    const JobKind kind = ParseJobKind(counts.ColumnText(3)).value_or(JobKind::kTrial);
    sweep.episodes_expected += ExpectedEpisodes(KindInfo(kind), counts.ColumnInt(2));
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
                   Statement::Prepare(db, absl::StrCat(SweepSelectSql(), " WHERE s.name = ?")));
  query.Bind(1, name);
  ASSIGN_OR_RETURN(bool row, query.Step());
  if (!row) return absl::NotFoundError(absl::StrCat("no sweep named '", name, "'"));
  return ReadSweepRow(db, query);
}


// After the view's columns: the sweep's shared trial options (StoredJobOptions).
const std::string& JobSelectSql() {
  static const std::string sql =
      absl::StrCat("SELECT ", JobView().select_list,
                   ", s.trial_options_json FROM jobs j JOIN sweeps s ON s.id = j.sweep_id");
  return sql;
}

JobRecord ReadJobRow(const Statement& row, SharedOptionsCache* cache) {
  JobRecord job;
  const int shared_column = ReadRecord(row, 0, JobView().fields, &job);
  if (job.options.empty()) {
    std::optional<std::string> shared;
    if (!row.ColumnIsNull(shared_column)) shared = row.ColumnText(shared_column);
    job.options = StoredJobOptions(std::string(), job.kind, job.method, job.seed, job.variant,
                                   shared, cache);
  }
  job.episodes_expected =
      static_cast<int>(ExpectedEpisodes(KindInfo(job.kind), job.episodes_expected));
  return job;
}

absl::StatusOr<JobRecord> LoadJob(Db& db, int64_t job_id) {
  ASSIGN_OR_RETURN(Statement query,
                   Statement::Prepare(db, absl::StrCat(JobSelectSql(), " WHERE j.id = ?")));
  query.Bind(1, job_id);
  ASSIGN_OR_RETURN(bool row, query.Step());
  if (!row) return absl::NotFoundError(absl::StrCat("no job with id ", job_id));
  return ReadJobRow(query);
}


// Loads the attempt and the job's latest attempt number. NotFound if the job
// does not exist; Aborted if the attempt does not exist.
absl::StatusOr<OpenAttempt> LoadAttempt(Db& db, const LeaseKey& key) {
  ASSIGN_OR_RETURN(Statement query,
                   Statement::Prepare(db, "SELECT j.attempts, j.episodes_expected, j.sweep_id, "
                                          "a.state, a.worker_id, j.kind, a.lease_expires_ms "
                                          "FROM jobs j LEFT JOIN "
                                          "attempts a ON a.job_id = j.id AND a.attempt = ? "
                                          "WHERE j.id = ?"));
  query.Bind(1, key.attempt).Bind(2, key.job_id);
  ASSIGN_OR_RETURN(bool row, query.Step());
  if (!row) return absl::NotFoundError(absl::StrCat("no job with id ", key.job_id));
  OpenAttempt attempt;
  attempt.job_attempts = static_cast<int>(query.ColumnInt(0));
  attempt.kind = ParseJobKind(query.ColumnText(5)).value_or(JobKind::kTrial);
  attempt.episodes_expected =
      static_cast<int>(ExpectedEpisodes(KindInfo(attempt.kind), query.ColumnInt(1)));
  attempt.sweep_id = query.ColumnInt(2);
  if (query.ColumnIsNull(3)) {
    return absl::AbortedError(absl::StrCat("job ", key.job_id, " has no attempt ", key.attempt,
                                           " (latest is ", attempt.job_attempts, ")"));
  }
  attempt.state = ParseAttemptState(query.ColumnText(3)).value_or(AttemptState::kRunning);
  attempt.worker_id = query.ColumnText(4);
  attempt.lease_expires_ms = query.ColumnInt(6);
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

std::string EpisodeInsertSql() {
  const auto& table = learner::EpisodeFields();
  std::vector<std::string> marks(table.size() + 4, "?");
  return absl::StrCat("INSERT INTO episodes(job_id, attempt, ", RecordColumnList(table, true),
                      ", details_json, reported_ms) VALUES(", absl::StrJoin(marks, ", "),
                      ") ON CONFLICT(job_id, attempt, episode) DO NOTHING");
}

void BindEpisode(Statement& insert, const LeaseKey& key, const Episode& episode,
                 int64_t reported_ms) {
  insert.Bind(1, key.job_id).Bind(2, key.attempt);
  const int next =
      BindRecord<learner::EpisodeSummary>(insert, 3, learner::EpisodeFields(), episode);
  insert.Bind(next, episode.details_json).Bind(next + 1, reported_ms);
}

namespace {

absl::Status InsertEpisodes(Db& db, const LeaseKey& key, int episodes_expected,
                            const std::vector<Episode>& episodes, int64_t now_ms) {
  if (episodes.empty()) return absl::OkStatus();
  ASSIGN_OR_RETURN(Statement insert, Statement::Prepare(db, EpisodeInsertSql()));
  for (const Episode& episode : episodes) {
    if (episode.episode < 0 || episode.episode >= episodes_expected) {
      return absl::InvalidArgumentError(
          absl::StrCat("episode ", episode.episode, " of job ", key.job_id,
                       " is out of range: the trial has episodes 0..", episodes_expected - 1));
    }
    BindEpisode(insert, key, episode, now_ms);
    RETURN_IF_ERROR(insert.Run());
    insert.Reset();
  }
  return absl::OkStatus();
}

// Rows of a study table: the row's key, then the record's columns
// (sqlite_records.h), then reported_ms.
template <typename Record, typename Row>
absl::Status InsertStudyTable(Db& db, const LeaseKey& key, absl::string_view table,
                              absl::string_view what, const record::FieldTable<Record>& fields,
                              const std::vector<Row>& rows, int64_t now_ms) {
  if (rows.empty()) return absl::OkStatus();
  std::vector<std::string> marks(fields.size() + 4, "?");
  ASSIGN_OR_RETURN(Statement insert,
                   Statement::Prepare(db, absl::StrCat("INSERT INTO ", table,
                                                       "(job_id, attempt, idx, ",
                                                       RecordColumnList(fields, true),
                                                       ", reported_ms) VALUES(",
                                                       absl::StrJoin(marks, ", "),
                                                       ") ON CONFLICT(job_id, attempt, idx) "
                                                       "DO NOTHING")));
  for (const Row& row : rows) {
    if (row.index < 0) {
      return absl::InvalidArgumentError(
          absl::StrCat(what, " index ", row.index, " of job ", key.job_id, " is negative"));
    }
    insert.Bind(1, key.job_id).Bind(2, key.attempt).Bind(3, row.index);
    const int next = BindRecord<Record>(insert, 4, fields, row);
    insert.Bind(next, now_ms);
    RETURN_IF_ERROR(insert.Run());
    insert.Reset();
  }
  return absl::OkStatus();
}

}  // namespace

absl::Status InsertResults(Db& db, const LeaseKey& key, const OpenAttempt& attempt,
                           const JobResults& results, int64_t now_ms) {
  if (results.empty()) return absl::OkStatus();
  // Ownership first (job_kinds.h), so each table's insert below sees only
  // rows of its own kind's jobs.
  RETURN_IF_ERROR(CheckOwnedTables(KindInfo(attempt.kind), key.job_id, results));
  RETURN_IF_ERROR(
      InsertEpisodes(db, key, attempt.episodes_expected, results.episodes, now_ms));
  RETURN_IF_ERROR(InsertStudyTable(db, key, "study_cells", "study cell", study::CellFields(),
                                   results.study.cells, now_ms));
  return InsertStudyTable(db, key, "study_references", "study reference",
                          study::ReferenceFields(), results.study.references, now_ms);
}

absl::StatusOr<ResultTotals> CountResults(Db& db, const LeaseKey& key, const JobKindInfo& kind) {
  ResultTotals stored;
  for (const ResultTable* table : kind.tables) {
    ASSIGN_OR_RETURN(Statement count,
                     Statement::Prepare(db, absl::StrCat("SELECT COUNT(*) FROM ", table->name,
                                                         " WHERE job_id = ? AND attempt = ?")));
    count.Bind(1, key.job_id).Bind(2, key.attempt);
    ASSIGN_OR_RETURN(bool row, count.Step());
    stored.*table->total = row ? static_cast<int>(count.ColumnInt(0)) : 0;
  }
  return stored;
}

absl::StatusOr<std::vector<int>> MissingRows(Db& db, const LeaseKey& key,
                                             const ResultTable& table, int total) {
  ASSIGN_OR_RETURN(Statement present,
                   Statement::Prepare(db, absl::StrCat("SELECT ", table.index_column, " FROM ",
                                                       table.name,
                                                       " WHERE job_id = ? AND attempt = ? AND ",
                                                       table.index_column, " < ?")));
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
  const JobKindInfo& kind = KindInfo(attempt.kind);
  if (!kind.checkpoints) {
    return absl::InvalidArgumentError(absl::StrCat("job ", key.job_id, " is a ", kind.name,
                                                   " job; ", kind.name,
                                                   " jobs keep no checkpoints"));
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


// CreateSweep inside the caller's transaction: *created tells whether it
// was inserted (false: a sweep of that name and hash existed).
absl::StatusOr<QueuedJobInserter> QueuedJobInserter::Prepare(Db& db, int64_t sweep_id,
                                                             int64_t first_ordinal) {
  ASSIGN_OR_RETURN(Statement insert, Statement::Prepare(db, R"sql(
INSERT INTO jobs(sweep_id, ordinal, method, seed, variant, options_json, episodes_expected, state,
                 kind, payload)
VALUES(?, ?, ?, ?, ?, ?, ?, 'queued', ?, ?))sql"));
  ASSIGN_OR_RETURN(Statement shared, Statement::Prepare(
      db, "SELECT trial_options_json FROM sweeps WHERE id = ? AND trial_options_json IS NOT NULL"));
  shared.Bind(1, sweep_id);
  ASSIGN_OR_RETURN(bool has_shared, shared.Step());
  std::optional<OptionPairs> shared_options;
  if (has_shared) shared_options = OptionsFromJson(shared.ColumnText(0));
  return QueuedJobInserter(db, std::move(insert), sweep_id, first_ordinal,
                           std::move(shared_options));
}

absl::StatusOr<std::string> QueuedJobInserter::StoredOptions(const NewJob& job) {
  if (job.kind != JobKind::kTrial || job.options.empty()) return OptionsToJson(job.options);
  if (!shared_options_) {
    ASSIGN_OR_RETURN(Statement set, Statement::Prepare(
        *db_, "UPDATE sweeps SET trial_options_json = ? WHERE id = ?"));
    set.Bind(1, OptionsToJson(job.options)).Bind(2, sweep_id_);
    RETURN_IF_ERROR(set.Run());
    shared_options_ = job.options;
  }
  // Stored compactly only where both reads give back exactly this list: the
  // same keys in the same order, differing at most in the job's own keys.
  // StoredJobOptions takes the seed as the INTEGER column reads back,
  // JobOptionsJsonSql the job_options value (the text as submitted).
  int64_t seed = 0;
  if (!absl::SimpleAtoi(job.seed, &seed)) return OptionsToJson(job.options);
  const bool from_columns =
      WithJobValues(*shared_options_, JobOptionPairs(job.method, std::to_string(seed),
                                                     job.variant)) == job.options;
  const bool from_job_options =
      WithJobValues(*shared_options_, JobOptionPairs(job.method, job.seed, job.variant)) ==
      job.options;
  return from_columns && from_job_options ? std::string() : OptionsToJson(job.options);
}

absl::Status QueuedJobInserter::Insert(const NewJob& job) {
  ASSIGN_OR_RETURN(const std::string stored_options, StoredOptions(job));
  insert_.Bind(1, sweep_id_).Bind(2, next_ordinal_).Bind(3, job.method).Bind(4, job.seed);
  insert_.Bind(5, job.variant).Bind(6, stored_options);
  insert_.Bind(7, EpisodesExpectedColumn(KindInfo(job.kind), job.episodes_expected));
  insert_.Bind(8, ToString(job.kind)).Bind(9, job.payload);
  RETURN_IF_ERROR(insert_.Run());
  insert_.Reset();
  RETURN_IF_ERROR(WriteJobOptions(*db_, db_->LastInsertRowId(), job.method, job.seed, job.variant));
  ++next_ordinal_;
  ++inserted_;
  return absl::OkStatus();
}

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
  insert.Bind(9, sweep.max_lost_leases).Bind(10, sweep.max_concurrent);
  insert.Bind(11, sweep.created_ms > 0 ? sweep.created_ms : now_ms);
  RETURN_IF_ERROR(insert.Run());
  const int64_t sweep_id = db.LastInsertRowId();
  ASSIGN_OR_RETURN(QueuedJobInserter jobs, QueuedJobInserter::Prepare(db, sweep_id, 0));
  RETURN_IF_ERROR(sweep.ForEachJob([&](const NewJob& job) { return jobs.Insert(job); }));
  RETURN_IF_ERROR(internal::CreateSweepView(db, sweep_id, sweep.name));
  *created = true;
  return AddEvent(db, now_ms, sweep_id, 0, 0, "sweep_submitted",
                  absl::StrCat(jobs.inserted(), " jobs, spec ", sweep.spec_hash));
}


}  // namespace totalgrad::storage::internal
