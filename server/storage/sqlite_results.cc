// SqliteStore: the results reads: trial results, episode export, study rows
// (sqlite_store.h).
#include <algorithm>
#include <set>
#include <utility>

#include <nlohmann/json.hpp>

#include "absl/strings/str_cat.h"
#include "absl/strings/str_join.h"
#include "server/common/status_macros.h"
#include "server/storage/sqlite_internal.h"
#include "server/storage/sqlite_schema.h"
#include "server/storage/sqlite_store.h"

namespace totalgrad::storage {

using internal::Db;
using internal::Statement;
using namespace internal;  // the row helpers of sqlite_internal.h

namespace {

// The first four columns of both study-row queries: job, attempt, the job's
// study name, and whether this attempt is the job's completed one.
template <typename StudyRecord>
void ReadStudyRowHeader(Statement& query, StudyRecord* record) {
  record->job_id = query.ColumnInt(0);
  record->attempt = static_cast<int>(query.ColumnInt(1));
  record->study = query.ColumnText(2);
  record->final_attempt = query.ColumnInt(3) != 0;
}


}  // namespace

absl::StatusOr<std::vector<TrialResultRecord>> SqliteStore::ListTrialResults(
    const std::string& sweep_name) {
  absl::MutexLock lock(&read_mutex_);
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
  absl::MutexLock lock(&read_mutex_);
  RETURN_IF_ERROR(reader_.Exec("BEGIN"));  // one snapshot for cells and references
  const absl::Status status = [&]() ABSL_EXCLUSIVE_LOCKS_REQUIRED(read_mutex_) -> absl::Status {
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


}  // namespace totalgrad::storage
