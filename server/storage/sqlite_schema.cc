#include "server/storage/sqlite_schema.h"

#include <algorithm>
#include <cmath>
#include <optional>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "absl/strings/numbers.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/str_split.h"
#include "runtime/status_macros.h"
#include "server/storage/sqlite_internal.h"

namespace totalgrad::storage::internal {
namespace {


// The schema of version 1; docs/results_schema.md explains every column. A
// new database is created as version 1 and migrated, in one transaction, so
// new and migrated databases have the same schema.
constexpr char kSchema[] = R"sql(
CREATE TABLE meta(
  key TEXT PRIMARY KEY,
  value TEXT NOT NULL
) WITHOUT ROWID;
CREATE TABLE sweeps(
  id INTEGER PRIMARY KEY,
  name TEXT NOT NULL UNIQUE,
  description TEXT NOT NULL DEFAULT '',
  state TEXT NOT NULL CHECK(state IN ('running', 'paused', 'cancelled')),
  canonical_spec TEXT NOT NULL,
  spec_hash TEXT NOT NULL,
  source_name TEXT NOT NULL DEFAULT '',
  source_text TEXT NOT NULL DEFAULT '',
  coordinator_build TEXT NOT NULL,
  max_attempts INTEGER NOT NULL CHECK(max_attempts >= 1),
  max_lost_leases INTEGER NOT NULL CHECK(max_lost_leases >= 1),
  max_concurrent INTEGER NOT NULL CHECK(max_concurrent >= 0),
  created_ms INTEGER NOT NULL
);
CREATE TABLE jobs(
  id INTEGER PRIMARY KEY,
  sweep_id INTEGER NOT NULL REFERENCES sweeps(id),
  ordinal INTEGER NOT NULL,
  method TEXT NOT NULL,
  seed TEXT NOT NULL,
  variant TEXT NOT NULL,
  options_json TEXT NOT NULL,
  episodes_expected INTEGER NOT NULL CHECK(episodes_expected >= 1),
  state TEXT NOT NULL
      CHECK(state IN ('queued', 'running', 'completed', 'failed', 'cancelled')),
  attempts INTEGER NOT NULL DEFAULT 0,
  failures INTEGER NOT NULL DEFAULT 0,
  lost_leases INTEGER NOT NULL DEFAULT 0,
  completed_attempt INTEGER,
  success INTEGER,
  final_eval_cost REAL,
  last_error TEXT NOT NULL DEFAULT '',
  UNIQUE(sweep_id, ordinal)
);
CREATE INDEX jobs_by_state ON jobs(state, sweep_id, ordinal);
CREATE TABLE attempts(
  job_id INTEGER NOT NULL REFERENCES jobs(id),
  attempt INTEGER NOT NULL CHECK(attempt >= 1),
  state TEXT NOT NULL CHECK(state IN
      ('running', 'completed', 'failed', 'lease_lost', 'released', 'cancelled')),
  worker_id TEXT NOT NULL,
  worker_host TEXT NOT NULL,
  worker_build TEXT NOT NULL,
  started_ms INTEGER NOT NULL,
  lease_expires_ms INTEGER NOT NULL,
  ended_ms INTEGER,
  error TEXT NOT NULL DEFAULT '',
  PRIMARY KEY(job_id, attempt)
) WITHOUT ROWID;
CREATE INDEX open_attempts_by_expiry ON attempts(lease_expires_ms) WHERE state = 'running';
CREATE INDEX open_attempts_by_worker ON attempts(worker_id) WHERE state = 'running';
CREATE TABLE episodes(
  job_id INTEGER NOT NULL,
  attempt INTEGER NOT NULL,
  episode INTEGER NOT NULL CHECK(episode >= 0),
  real_cost REAL,
  eval_cost_mean REAL,
  eval_cost_std REAL,
  predicted_cost REAL,
  optimisation_seconds REAL,
  details_json TEXT NOT NULL DEFAULT '',
  reported_ms INTEGER NOT NULL,
  PRIMARY KEY(job_id, attempt, episode),
  FOREIGN KEY(job_id, attempt) REFERENCES attempts(job_id, attempt)
) WITHOUT ROWID;
CREATE TABLE workers(
  worker_id TEXT PRIMARY KEY,
  host TEXT NOT NULL,
  build TEXT NOT NULL,
  slots INTEGER NOT NULL,
  first_seen_ms INTEGER NOT NULL,
  last_seen_ms INTEGER NOT NULL,
  draining INTEGER NOT NULL DEFAULT 0
) WITHOUT ROWID;
CREATE TABLE events(
  id INTEGER PRIMARY KEY,
  ms INTEGER NOT NULL,
  sweep_id INTEGER REFERENCES sweeps(id),
  job_id INTEGER REFERENCES jobs(id),
  attempt INTEGER NOT NULL DEFAULT 0,
  kind TEXT NOT NULL,
  message TEXT NOT NULL DEFAULT ''
);
CREATE INDEX events_by_job ON events(job_id, id);
)sql";

// Version 1 -> 2: study jobs (issue 6). A job has a kind and, for studies, a
// payload (the self-contained study spec); study results go in study_cells
// (one row per study::CellResult, the columns of the study's table.csv) and
// study_references (one per horizon, references.csv plus the vectors), keyed
// like episodes by (job, attempt, index). Study jobs store
// episodes_expected = 1 (the column's CHECK) and read it back as 0.
constexpr char kMigration2[] = R"sql(
ALTER TABLE jobs ADD COLUMN kind TEXT NOT NULL DEFAULT 'trial' CHECK(kind IN ('trial', 'study'));
ALTER TABLE jobs ADD COLUMN payload TEXT NOT NULL DEFAULT '';
CREATE TABLE study_cells(
  job_id INTEGER NOT NULL,
  attempt INTEGER NOT NULL,
  idx INTEGER NOT NULL CHECK(idx >= 0),
  estimator TEXT NOT NULL,
  method TEXT NOT NULL,
  particles INTEGER NOT NULL,
  horizon INTEGER NOT NULL,
  replicates INTEGER NOT NULL,
  nonfinite INTEGER NOT NULL,
  errors INTEGER NOT NULL,
  time_min_s REAL,
  time_median_s REAL,
  rel_rmse REAL,
  rel_bias REAL,
  rel_bias_noise REAL,
  total_variance REAL,
  cos_mean REAL,
  objective_mean REAL,
  ess_mean REAL,
  ess_min REAL,
  k_lr_mean REAL,
  reference_agrees INTEGER NOT NULL,
  reference_floor REAL,
  budget_hit INTEGER NOT NULL,
  omitted INTEGER NOT NULL,
  note TEXT NOT NULL DEFAULT '',
  error TEXT NOT NULL DEFAULT '',
  omission_reason TEXT NOT NULL DEFAULT '',
  k_lr_per_step_json TEXT NOT NULL DEFAULT '[]',
  reported_ms INTEGER NOT NULL,
  PRIMARY KEY(job_id, attempt, idx),
  FOREIGN KEY(job_id, attempt) REFERENCES attempts(job_id, attempt)
) WITHOUT ROWID;
CREATE TABLE study_references(
  job_id INTEGER NOT NULL,
  attempt INTEGER NOT NULL,
  idx INTEGER NOT NULL CHECK(idx >= 0),
  horizon INTEGER NOT NULL,
  norm REAL,
  relative_error REAL,
  floor REAL,
  objective REAL,
  used_json TEXT NOT NULL DEFAULT '[]',
  replicates_json TEXT NOT NULL DEFAULT '[]',
  agreement_max_z REAL,
  agreement_mean_z2 REAL,
  agree INTEGER NOT NULL,
  seconds REAL,
  note TEXT NOT NULL DEFAULT '',
  gradient_json TEXT NOT NULL DEFAULT '[]',
  standard_error_json TEXT NOT NULL DEFAULT '[]',
  reported_ms INTEGER NOT NULL,
  PRIMARY KEY(job_id, attempt, idx),
  FOREIGN KEY(job_id, attempt) REFERENCES attempts(job_id, attempt)
) WITHOUT ROWID;
)sql";

// Version 2 -> 3: trial checkpoints (issue 12). The latest checkpoint of
// each attempt (core/learner/checkpoint.h, opaque here), from which a new
// attempt of the job resumes.
constexpr char kMigration3[] = R"sql(
CREATE TABLE checkpoints(
  job_id INTEGER NOT NULL,
  attempt INTEGER NOT NULL,
  episode INTEGER NOT NULL CHECK(episode >= 0),
  format_version INTEGER NOT NULL,
  data BLOB NOT NULL,
  reported_ms INTEGER NOT NULL,
  PRIMARY KEY(job_id, attempt),
  FOREIGN KEY(job_id, attempt) REFERENCES attempts(job_id, attempt)
) WITHOUT ROWID;
)sql";


// Version 3 -> 4 (issue 15): what a reader of the file needs without the
// coordinator. job_options: one row per job and swept key (the grid axes:
// method, seed and the variant's keys), the value as its canonical text and,
// when it is a number, as a number (so SQL and pandas compare numbers);
// episodes.cpu_seconds: the episode's CPU time (also in details_json, where
// older workers do not have it: NULL then); meta: what the file is.
constexpr char kMigration4[] = R"sql(
CREATE TABLE job_options(
  job_id INTEGER NOT NULL REFERENCES jobs(id),
  key TEXT NOT NULL,
  value TEXT NOT NULL,
  number NUMERIC,
  PRIMARY KEY(job_id, key)
) WITHOUT ROWID;
ALTER TABLE episodes ADD COLUMN cpu_seconds REAL;
UPDATE episodes SET cpu_seconds = json_extract(details_json, '$.cpu_seconds')
  WHERE json_valid(details_json) AND json_type(details_json, '$.cpu_seconds') IN ('real', 'integer');
CREATE VIEW episode_rows AS
  SELECT s.name AS sweep, j.id AS job_id, j.method AS method, CAST(j.seed AS INTEGER) AS seed,
         j.variant AS variant, e.attempt AS attempt,
         (e.attempt = COALESCE(j.completed_attempt, j.attempts)) AS final_attempt,
         e.episode AS episode, e.real_cost AS real_cost, e.eval_cost_mean AS eval_cost_mean,
         e.eval_cost_std AS eval_cost_std, e.predicted_cost AS predicted_cost,
         e.optimisation_seconds AS wall_seconds, e.cpu_seconds AS cpu_seconds,
         j.state AS job_state, j.success AS success, j.final_eval_cost AS final_eval_cost,
         a.worker_build AS worker_build
  FROM episodes e JOIN jobs j ON j.id = e.job_id JOIN sweeps s ON s.id = j.sweep_id
       JOIN attempts a ON a.job_id = e.job_id AND a.attempt = e.attempt;
)sql";

// Version 4 -> 5 (issue 15): jobs.seed becomes an INTEGER column (it was
// TEXT: a reader of the raw table compared seeds as strings). SQLite cannot
// change a column's type, so the table is rebuilt: copied into a new one with
// the same columns, the old one dropped, the new one renamed. The views read
// jobs, so they are dropped first and recreated after (Migrate). The caller
// runs this with foreign_keys OFF (dropping a referenced table would
// otherwise delete-check every row) and Migrate checks the keys at the end.
constexpr char kMigration5[] = R"sql(
DROP VIEW IF EXISTS episode_rows;
CREATE TABLE jobs_v5(
  id INTEGER PRIMARY KEY,
  sweep_id INTEGER NOT NULL REFERENCES sweeps(id),
  ordinal INTEGER NOT NULL,
  method TEXT NOT NULL,
  seed INTEGER NOT NULL CHECK(typeof(seed) = 'integer' AND seed >= 0),
  variant TEXT NOT NULL,
  options_json TEXT NOT NULL,
  episodes_expected INTEGER NOT NULL CHECK(episodes_expected >= 1),
  state TEXT NOT NULL
      CHECK(state IN ('queued', 'running', 'completed', 'failed', 'cancelled')),
  attempts INTEGER NOT NULL DEFAULT 0,
  failures INTEGER NOT NULL DEFAULT 0,
  lost_leases INTEGER NOT NULL DEFAULT 0,
  completed_attempt INTEGER,
  success INTEGER,
  final_eval_cost REAL,
  last_error TEXT NOT NULL DEFAULT '',
  kind TEXT NOT NULL DEFAULT 'trial' CHECK(kind IN ('trial', 'study')),
  payload TEXT NOT NULL DEFAULT '',
  UNIQUE(sweep_id, ordinal)
);
INSERT INTO jobs_v5(id, sweep_id, ordinal, method, seed, variant, options_json,
                    episodes_expected, state, attempts, failures, lost_leases,
                    completed_attempt, success, final_eval_cost, last_error, kind, payload)
  SELECT id, sweep_id, ordinal, method, CAST(seed AS INTEGER), variant, options_json,
         episodes_expected, state, attempts, failures, lost_leases,
         completed_attempt, success, final_eval_cost, last_error, kind, payload FROM jobs;
DROP TABLE jobs;
ALTER TABLE jobs_v5 RENAME TO jobs;
CREATE INDEX jobs_by_state ON jobs(state, sweep_id, ordinal);
)sql";

// Version 5 -> 6 (issue 13, one description per record): the stored
// reference gradient gains agreement_resolution, the field that core's
// study::ReferenceGradient had and the stored copy had dropped. Rows written
// before hold NULL: "not computed", as results.json files written before the
// field existed read. The columns of both study tables are now generated
// from the records' field tables (sqlite_records.h); a field added to a
// table is a column added here.
constexpr char kMigration6[] = R"sql(
ALTER TABLE study_references ADD COLUMN agreement_resolution REAL;
)sql";

// Version 6 -> 7 (issue 25): episodes.held_fraction, the rollout verdict's
// fraction of a trial's final-policy rollouts that were held (NULL on every
// other episode and in rows stored before; the views are recreated with the
// column, Migrate); attempts.origin, where an attempt that did not run here
// came from ('' for one a worker ran: `job supersede` copies another job's
// completed attempt and names it, "job 57 attempt 1 of sweep S").
constexpr char kMigration7[] = R"sql(
ALTER TABLE episodes ADD COLUMN held_fraction REAL;
ALTER TABLE attempts ADD COLUMN origin TEXT NOT NULL DEFAULT '';
)sql";

// Version 7 -> 8 (issue 27): the optimisation diagnostics of each episode
// (learner::OptimisationDiagnostics); NULL in rows stored before, which read
// as absent, not zero.
constexpr char kMigration8[] = R"sql(
ALTER TABLE episodes ADD COLUMN gradient_norm_first REAL;
ALTER TABLE episodes ADD COLUMN gradient_norm_middle REAL;
ALTER TABLE episodes ADD COLUMN gradient_norm_last REAL;
ALTER TABLE episodes ADD COLUMN gradient_norm_mean REAL;
ALTER TABLE episodes ADD COLUMN gradient_snr_first REAL;
ALTER TABLE episodes ADD COLUMN gradient_snr_middle REAL;
ALTER TABLE episodes ADD COLUMN gradient_snr_last REAL;
ALTER TABLE episodes ADD COLUMN gradient_snr_mean REAL;
ALTER TABLE episodes ADD COLUMN step_norm_first REAL;
ALTER TABLE episodes ADD COLUMN step_norm_middle REAL;
ALTER TABLE episodes ADD COLUMN step_norm_last REAL;
ALTER TABLE episodes ADD COLUMN step_norm_mean REAL;
ALTER TABLE episodes ADD COLUMN ess_min REAL;
ALTER TABLE episodes ADD COLUMN ess_median REAL;
ALTER TABLE episodes ADD COLUMN ess_low_fraction REAL;
ALTER TABLE episodes ADD COLUMN lr_share_json TEXT;
)sql";

// Version 9 -> 10 (issue 28): a trial job's options are mostly its sweep's
// protocol, the same ~55 pairs in every job (1.46 of the 2.05 KB a job took).
// sweeps.trial_options_json keeps them once per sweep; a trial job whose
// options are those with its own job_options values put in stores '' in
// jobs.options_json (the store checks that when it inserts the job, and
// stores the whole list otherwise). Rows stored before keep their lists.
// The view job_option_lists gives every job's whole list either way.
// sweeps is rebuilt with its numbers and short texts first and the texts
// that grow with a spec last: SQLite reads a column by walking the row, so a
// lease's read of a sweep's budgets (max_attempts after canonical_spec and
// source_text) walked every overflow page of a spec that lists 100,000
// seeds: half of a heartbeat's instructions at 100,000 queued. The caller
// runs this with foreign_keys OFF (jobs refer to sweeps) and the views
// dropped (they read sweeps); Migrate checks the keys after.
constexpr char kMigration10[] = R"sql(
CREATE TABLE sweeps_v10(
  id INTEGER PRIMARY KEY,
  name TEXT NOT NULL UNIQUE,
  state TEXT NOT NULL CHECK(state IN ('running', 'paused', 'cancelled')),
  max_attempts INTEGER NOT NULL CHECK(max_attempts >= 1),
  max_lost_leases INTEGER NOT NULL CHECK(max_lost_leases >= 1),
  max_concurrent INTEGER NOT NULL CHECK(max_concurrent >= 0),
  created_ms INTEGER NOT NULL,
  spec_hash TEXT NOT NULL,
  coordinator_build TEXT NOT NULL,
  source_name TEXT NOT NULL DEFAULT '',
  description TEXT NOT NULL DEFAULT '',
  trial_options_json TEXT,
  canonical_spec TEXT NOT NULL,
  source_text TEXT NOT NULL DEFAULT ''
);
INSERT INTO sweeps_v10(id, name, state, max_attempts, max_lost_leases, max_concurrent, created_ms,
                       spec_hash, coordinator_build, source_name, description, trial_options_json,
                       canonical_spec, source_text)
  SELECT id, name, state, max_attempts, max_lost_leases, max_concurrent, created_ms, spec_hash,
         coordinator_build, source_name, description, NULL, canonical_spec, source_text
  FROM sweeps;
DROP TABLE sweeps;
ALTER TABLE sweeps_v10 RENAME TO sweeps;
)sql";

void BindNumber(Statement& statement, int index, const std::string& text) {
  const TextNumber number = ParseTextNumber(text);
  if (number.integer) {
    statement.Bind(index, *number.integer);
  } else if (number.real) {
    statement.Bind(index, *number.real);
  } else {
    statement.BindNull(index);
  }
}

// "key=value key=value" -> pairs (values never hold spaces: canonical texts).
std::vector<std::pair<std::string, std::string>> VariantPairs(const std::string& variant) {
  std::vector<std::pair<std::string, std::string>> pairs;
  for (absl::string_view item : absl::StrSplit(variant, ' ', absl::SkipEmpty())) {
    const size_t eq = item.find('=');
    if (eq == absl::string_view::npos) continue;
    pairs.emplace_back(std::string(item.substr(0, eq)), std::string(item.substr(eq + 1)));
  }
  return pairs;
}

// A rebuilt table runs with foreign_keys OFF (Migrate's caller): DataLoss
// naming the first row that refers to a missing one, if any.
absl::Status CheckKeysAfterRebuilding(Db& db, absl::string_view table) {
  ASSIGN_OR_RETURN(Statement keys, Statement::Prepare(db, "PRAGMA foreign_key_check"));
  ASSIGN_OR_RETURN(bool violation, keys.Step());
  if (!violation) return absl::OkStatus();
  return absl::DataLossError(absl::StrCat("after rebuilding ", table, ", table ",
                                          keys.ColumnText(0), " row ", keys.ColumnInt(1),
                                          " refers to a missing row of ", keys.ColumnText(2)));
}

}  // namespace

const char* SchemaText() { return kSchema; }

TextNumber ParseTextNumber(const std::string& text) {
  int64_t integer;
  double real;
  if (absl::SimpleAtoi(text, &integer)) return {integer, std::nullopt};
  if (absl::SimpleAtod(text, &real) && std::isfinite(real)) return {std::nullopt, real};
  return {};
}

OptionPairs JobOptionPairs(const std::string& method, const std::string& seed,
                           const std::string& variant) {
  OptionPairs pairs = {{"method", method}, {"seed", seed}};
  for (auto& pair : VariantPairs(variant)) pairs.push_back(std::move(pair));
  return pairs;
}

absl::Status WriteJobOptions(Db& db, int64_t job_id, const std::string& method,
                             const std::string& seed, const std::string& variant) {
  ASSIGN_OR_RETURN(Statement insert,
                   Statement::Prepare(db, "INSERT OR REPLACE INTO job_options(job_id, key, value, "
                                          "number) VALUES(?, ?, ?, ?)"));
  for (const auto& [key, value] : JobOptionPairs(method, seed, variant)) {
    insert.Bind(1, job_id).Bind(2, key).Bind(3, value);
    BindNumber(insert, 4, value);
    RETURN_IF_ERROR(insert.Run());
    insert.Reset();
  }
  return absl::OkStatus();
}

absl::Status Migrate(Db& db, int64_t from) {
  if (from < 2) RETURN_IF_ERROR(db.Exec(kMigration2));
  if (from < 3) RETURN_IF_ERROR(db.Exec(kMigration3));
  if (from < 4) {
    RETURN_IF_ERROR(db.Exec(kMigration4));
    ASSIGN_OR_RETURN(Statement jobs,
                     Statement::Prepare(db, "SELECT id, method, seed, variant FROM jobs"));
    for (;;) {
      ASSIGN_OR_RETURN(bool row, jobs.Step());
      if (!row) break;
      RETURN_IF_ERROR(WriteJobOptions(db, jobs.ColumnInt(0), jobs.ColumnText(1),
                                      jobs.ColumnText(2), jobs.ColumnText(3)));
    }
  }
  if (from < 5) {
    // Every view reads jobs: drop them all, rebuild jobs; the views are
    // created again after the last migration (version 7's RecreateViews).
    RETURN_IF_ERROR(DropViews(db));
    {
      // A seed that is not an integer would be stored as 0 by the CAST and
      // then refused by the CHECK: name it instead.
      ASSIGN_OR_RETURN(Statement bad, Statement::Prepare(
          db, "SELECT id, seed FROM jobs WHERE CAST(CAST(seed AS INTEGER) AS TEXT) != seed "
              "OR CAST(seed AS INTEGER) < 0 LIMIT 1"));
      ASSIGN_OR_RETURN(bool row, bad.Step());
      if (row) {
        return absl::FailedPreconditionError(
            absl::StrCat("job ", bad.ColumnInt(0), " has seed '", bad.ColumnText(1),
                         "', which is not an integer in [0, 2^63): it cannot be migrated"));
      }
    }
    RETURN_IF_ERROR(db.Exec(kMigration5));
    // The views are created again after the last migration (RecreateViews),
    // with the columns of the latest version.
    RETURN_IF_ERROR(CheckKeysAfterRebuilding(db, "jobs"));
  }
  if (from < 6) RETURN_IF_ERROR(db.Exec(kMigration6));
  if (from < 7) RETURN_IF_ERROR(db.Exec(kMigration7));
  if (from < 8) RETURN_IF_ERROR(db.Exec(kMigration8));
  if (from < 10) {
    RETURN_IF_ERROR(DropViews(db));
    RETURN_IF_ERROR(db.Exec(kMigration10));
    RETURN_IF_ERROR(CheckKeysAfterRebuilding(db, "sweeps"));
  }
  // Version 9 changed only the views (every option and the export's names),
  // version 10 adds job_option_lists and drops the views' wall_seconds:
  // they are created again from the tables of the latest version.
  if (from < 10) RETURN_IF_ERROR(RecreateViews(db));
  RETURN_IF_ERROR(db.Exec(absl::StrCat(
      "INSERT OR REPLACE INTO meta(key, value) VALUES ('format', 'totalgrad coordinator database'), "
      "('schema_version', '", kSchemaVersion, "'), ('documentation', 'docs/results_schema.md')")));
  return db.Exec(absl::StrCat("PRAGMA user_version=", kSchemaVersion));
}

}  // namespace totalgrad::storage::internal
