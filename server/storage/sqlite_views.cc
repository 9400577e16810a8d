#include "server/storage/sqlite_schema.h"

#include <algorithm>
#include <string>
#include <vector>

#include "absl/strings/str_cat.h"
#include "absl/strings/str_format.h"
#include "absl/strings/str_join.h"
#include "runtime/status_macros.h"
#include "server/storage/sqlite_internal.h"

// The views of the coordinator database: what a reader of the file sees
// (episode_rows, one "episodes/<sweep>" per sweep, job_option_lists).
// docs/results_schema.md documents them.
namespace totalgrad::storage::internal {
namespace {

// One row per stored episode of every sweep, under the names of `results
// export -f csv` (version 9): the job's coordinates and outcome, the
// episode's record and the worker's build (version 9 also kept
// `wall_seconds`, optimisation_seconds' old name; version 10 dropped it).
// final_attempt is 1 for the attempt that completed the job, as in the
// exports (until version 8 it was also 1 for a running job's latest attempt).
constexpr char kEpisodeRowsView[] = R"sql(
CREATE VIEW episode_rows AS
  SELECT s.name AS sweep, j.id AS job_id, e.attempt AS attempt,
         (e.attempt = COALESCE(j.completed_attempt, 0)) AS final_attempt,
         j.method AS method, j.seed AS seed, j.variant AS variant,
         j.state AS job_state, j.success AS success, j.final_eval_cost AS final_eval_cost,
         e.episode AS episode, e.real_cost AS real_cost, e.eval_cost_mean AS eval_cost_mean,
         e.eval_cost_std AS eval_cost_std, e.predicted_cost AS predicted_cost,
         e.optimisation_seconds AS optimisation_seconds, e.cpu_seconds AS cpu_seconds,
         e.held_fraction AS held_fraction,
         e.gradient_norm_first AS gradient_norm_first, e.gradient_norm_middle AS gradient_norm_middle,
         e.gradient_norm_last AS gradient_norm_last, e.gradient_norm_mean AS gradient_norm_mean,
         e.gradient_snr_first AS gradient_snr_first, e.gradient_snr_middle AS gradient_snr_middle,
         e.gradient_snr_last AS gradient_snr_last, e.gradient_snr_mean AS gradient_snr_mean,
         e.step_norm_first AS step_norm_first, e.step_norm_middle AS step_norm_middle,
         e.step_norm_last AS step_norm_last, e.step_norm_mean AS step_norm_mean,
         e.ess_min AS ess_min, e.ess_median AS ess_median, e.ess_low_fraction AS ess_low_fraction,
         e.reported_ms AS reported_unix_ms, e.details_json AS details_json,
         a.worker_build AS worker_build
  FROM episodes e JOIN jobs j ON j.id = e.job_id JOIN sweeps s ON s.id = j.sweep_id
       JOIN attempts a ON a.job_id = e.job_id AND a.attempt = e.attempt;
)sql";

// episode_rows' columns after the job's and before the episode's: where a
// sweep's view puts the trial options.
constexpr char kJobColumns[] =
    "r.sweep, r.job_id, r.attempt, r.final_attempt, r.method, r.seed, r.variant, r.job_state, "
    "r.success, r.final_eval_cost";
constexpr char kEpisodeColumns[] =
    "r.episode, r.real_cost, r.eval_cost_mean, r.eval_cost_std, r.predicted_cost, "
    "r.optimisation_seconds, r.cpu_seconds, r.held_fraction, r.gradient_norm_first, "
    "r.gradient_norm_middle, r.gradient_norm_last, r.gradient_norm_mean, r.gradient_snr_first, "
    "r.gradient_snr_middle, r.gradient_snr_last, r.gradient_snr_mean, r.step_norm_first, "
    "r.step_norm_middle, r.step_norm_last, r.step_norm_mean, r.ess_min, r.ess_median, "
    "r.ess_low_fraction, r.reported_unix_ms, r.details_json, r.worker_build";

// `text` between two `quote`s, each `quote` inside doubled: SQL's quoting
// of identifiers ('"') and string literals ('\'').
std::string Quoted(const std::string& text, char quote) {
  std::string quoted(1, quote);
  for (char c : text) {
    if (c == quote) quoted += quote;
    quoted += c;
  }
  return quoted + quote;
}

// An SQL identifier in double quotes (a sweep name is A-Z a-z 0-9 . _ -, so
// it never contains a quote; doubling them keeps that true regardless).
std::string QuoteIdentifier(const std::string& name) { return Quoted(name, '"'); }

// An option's text as an SQL literal of its type (ParseTextNumber, as
// job_options.number types it): a number, or the text quoted.
std::string OptionLiteral(const std::string& text) {
  const TextNumber number = ParseTextNumber(text);
  if (number.integer) return std::to_string(*number.integer);
  if (number.real) return absl::StrFormat("%.17g", *number.real);
  return Quoted(text, '\'');
}

}  // namespace

std::string SweepViewName(const std::string& sweep_name) { return "episodes/" + sweep_name; }

absl::Status CreateSweepView(Db& db, int64_t sweep_id, const std::string& sweep_name) {
  // The swept keys other than method and seed: typed per row from job_options.
  ASSIGN_OR_RETURN(Statement keys, Statement::Prepare(db, R"sql(
SELECT o.key FROM job_options o JOIN jobs j ON j.id = o.job_id
WHERE j.sweep_id = ? AND o.key NOT IN ('method', 'seed')
GROUP BY o.key ORDER BY MIN(j.ordinal), o.key)sql"));
  keys.Bind(1, sweep_id);
  std::vector<std::string> swept;
  for (;;) {
    ASSIGN_OR_RETURN(bool row, keys.Step());
    if (!row) break;
    swept.push_back(keys.ColumnText(0));
  }
  // Every other option is the sweep's protocol, the same in every trial job
  // (SqliteStore::GrowSweep refuses jobs that would differ): a constant
  // column from the first trial job. A key that job lacks (added to the
  // options after it ran) is left out.
  ASSIGN_OR_RETURN(Statement first, Statement::Prepare(db, absl::StrCat(R"sql(
SELECT )sql", JobOptionsJsonSql(), R"sql( FROM jobs j
WHERE j.sweep_id = ? AND j.kind = 'trial' ORDER BY j.ordinal LIMIT 1)sql")));
  first.Bind(1, sweep_id);
  ASSIGN_OR_RETURN(bool has_trial, first.Step());
  const OptionPairs options = has_trial ? OptionsFromJson(first.ColumnText(0)) : OptionPairs();
  std::vector<std::string> columns;
  const auto swept_column = [](const std::string& key) {
    // Keys are trial option names ([a-z_0-9]): safe as identifiers; the
    // value is bound per row by the subquery, never built from data.
    return absl::StrCat("(SELECT COALESCE(o.number, o.value) FROM job_options o WHERE "
                        "o.job_id = r.job_id AND o.key = '", key, "') AS ", QuoteIdentifier(key));
  };
  std::vector<std::string> placed;
  for (const auto& [key, value] : options) {
    if (key == "method" || key == "seed") continue;
    const bool is_swept = std::find(swept.begin(), swept.end(), key) != swept.end();
    columns.push_back(is_swept ? swept_column(key)
                               : absl::StrCat(OptionLiteral(value), " AS ", QuoteIdentifier(key)));
    placed.push_back(key);
  }
  for (const std::string& key : swept) {
    if (std::find(placed.begin(), placed.end(), key) == placed.end()) columns.push_back(swept_column(key));
  }
  const std::string select = absl::StrCat(
      "SELECT ", kJobColumns, columns.empty() ? "" : ", ", absl::StrJoin(columns, ", "), ", ",
      kEpisodeColumns, " FROM episode_rows r WHERE r.sweep = (SELECT name FROM sweeps WHERE id = ",
      sweep_id, ")");
  const std::string view = QuoteIdentifier(SweepViewName(sweep_name));
  RETURN_IF_ERROR(db.Exec(absl::StrCat("DROP VIEW IF EXISTS ", view)));
  return db.Exec(absl::StrCat("CREATE VIEW ", view, " AS ", select));
}

absl::Status DropSweepView(Db& db, const std::string& sweep_name) {
  return db.Exec(
      absl::StrCat("DROP VIEW IF EXISTS ", QuoteIdentifier(SweepViewName(sweep_name))));
}

// Drops every sweep's view ("episodes/<name>"), job_option_lists and
// episode_rows.
absl::Status DropViews(Db& db) {
  std::vector<std::string> views;
  {
    ASSIGN_OR_RETURN(Statement list, Statement::Prepare(
        db, "SELECT name FROM sqlite_schema WHERE type = 'view' AND name LIKE 'episodes/%'"));
    for (;;) {
      ASSIGN_OR_RETURN(bool row, list.Step());
      if (!row) break;
      views.push_back(list.ColumnText(0));
    }
  }
  for (const std::string& view : views)
    RETURN_IF_ERROR(db.Exec(absl::StrCat("DROP VIEW ", QuoteIdentifier(view))));
  RETURN_IF_ERROR(db.Exec("DROP VIEW IF EXISTS job_option_lists"));
  return db.Exec("DROP VIEW IF EXISTS episode_rows");
}

// Drops the views and creates them again (after a column of theirs was
// added, or the tables they read were rebuilt).
absl::Status RecreateViews(Db& db) {
  RETURN_IF_ERROR(DropViews(db));
  RETURN_IF_ERROR(db.Exec(kEpisodeRowsView));
  RETURN_IF_ERROR(db.Exec(absl::StrCat("CREATE VIEW job_option_lists AS SELECT j.id AS job_id, ",
                                       JobOptionsJsonSql(), " AS options_json FROM jobs j")));
  ASSIGN_OR_RETURN(Statement sweeps, Statement::Prepare(db, "SELECT id, name FROM sweeps"));
  for (;;) {
    ASSIGN_OR_RETURN(bool row, sweeps.Step());
    if (!row) break;
    RETURN_IF_ERROR(CreateSweepView(db, sweeps.ColumnInt(0), sweeps.ColumnText(1)));
  }
  return absl::OkStatus();
}

}  // namespace totalgrad::storage::internal
