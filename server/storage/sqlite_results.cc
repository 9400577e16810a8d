// SqliteStore: the results reads: trial results, episode export, study rows
// (sqlite_store.h).
#include <algorithm>
#include <set>
#include <utility>

#include "absl/strings/str_cat.h"
#include "absl/strings/str_join.h"
#include "runtime/status_macros.h"
#include "server/storage/sqlite_internal.h"
#include "server/storage/sqlite_records.h"
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

// One study table's rows of a sweep (study_cells or study_references), every
// attempt's or the completing (else the latest) attempt's, in (job, attempt,
// index) order: the row's key, then the record's own columns through its
// field table, into `Record::*row` (a StudyCell or StudyReference).
template <typename Record, typename Row, typename Core>
absl::Status ReadStudyTable(Db& db, absl::string_view table,
                            const record::FieldTable<Core>& fields, int64_t sweep_id,
                            bool all_attempts, Row Record::*row, std::vector<Record>* out) {
  ASSIGN_OR_RETURN(Statement query, Statement::Prepare(db, absl::StrCat(
      "SELECT t.job_id, t.attempt, j.variant, COALESCE(j.completed_attempt, 0) = t.attempt, "
      "t.idx, ", RecordColumnList(fields, false, "t."), " FROM ", table, R"sql( t
JOIN jobs j ON j.id = t.job_id
WHERE j.sweep_id = ? AND (? OR t.attempt = COALESCE(j.completed_attempt, j.attempts))
ORDER BY t.job_id, t.attempt, t.idx)sql")));
  query.Bind(1, sweep_id).Bind(2, all_attempts ? 1 : 0);
  while (true) {
    ASSIGN_OR_RETURN(bool found, query.Step());
    if (!found) return absl::OkStatus();
    Record r;
    ReadStudyRowHeader(query, &r);
    (r.*row).index = static_cast<int>(query.ColumnInt(4));
    ReadRecord<Core>(query, 5, fields, &(r.*row));
    out->push_back(std::move(r));
  }
}


}  // namespace

absl::StatusOr<std::vector<results::CompletedTrial>> SqliteStore::ListTrialResults(
    const std::string& sweep_name) {
  absl::MutexLock lock(&read_mutex_);
  ASSIGN_OR_RETURN(Statement check, Statement::Prepare(reader_, "SELECT id FROM sweeps WHERE name = ?"));
  check.Bind(1, sweep_name);
  ASSIGN_OR_RETURN(bool found, check.Step());
  if (!found) return absl::NotFoundError(absl::StrCat("no sweep named '", sweep_name, "'"));
  const int64_t sweep_id = check.ColumnInt(0);
  ASSIGN_OR_RETURN(Statement query, Statement::Prepare(reader_, R"sql(
SELECT j.id, j.method, j.seed, j.variant, j.completed_attempt, j.success, j.final_eval_cost,
       (SELECT COUNT(*) FROM episodes e WHERE e.job_id = j.id AND e.attempt = j.completed_attempt),
       (SELECT e.held_fraction FROM episodes e WHERE e.job_id = j.id
        AND e.attempt = j.completed_attempt ORDER BY e.episode DESC LIMIT 1)
FROM jobs j WHERE j.sweep_id = ? AND j.state = 'completed' AND j.kind = 'trial'
ORDER BY j.ordinal)sql"));
  query.Bind(1, sweep_id);
  std::vector<results::CompletedTrial> results;
  while (true) {
    ASSIGN_OR_RETURN(bool row, query.Step());
    if (!row) break;
    results::CompletedTrial r;
    r.sweep = sweep_name;
    r.job_id = query.ColumnInt(0);
    r.method = query.ColumnText(1);
    r.seed = query.ColumnText(2);
    r.variant = query.ColumnText(3);
    r.attempt = static_cast<int>(query.ColumnInt(4));
    r.success = query.ColumnInt(5) != 0;
    r.final_eval_cost = query.ColumnDouble(6);
    r.episodes = static_cast<int>(query.ColumnInt(7));
    r.held_fraction = query.ColumnDouble(8);
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
  // The row's coordinates, then the episode's record (sqlite_records.h).
  ASSIGN_OR_RETURN(Statement query, Statement::Prepare(db, absl::StrCat(
      "SELECT e.job_id, e.attempt, j.method, j.seed, j.variant, e.details_json, e.reported_ms, "
      "COALESCE(j.completed_attempt, 0) = e.attempt, ",
      RecordColumnList(learner::EpisodeFields(), false, "e."), R"sql(
FROM episodes e JOIN jobs j ON j.id = e.job_id
WHERE j.sweep_id = ? AND (? OR e.attempt = COALESCE(j.completed_attempt, j.attempts))
ORDER BY e.job_id, e.attempt, e.episode)sql")));
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
    r.episode.details_json = query.ColumnText(5);
    r.reported_ms = query.ColumnInt(6);
    r.final_attempt = query.ColumnInt(7) != 0;
    ReadRecord<learner::EpisodeSummary>(query, 8, learner::EpisodeFields(), &r.episode);
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
    // The row's key, then the record's own columns (sqlite_records.h).
    RETURN_IF_ERROR(ReadStudyTable(reader_, "study_cells", study::CellFields(), sweep_id,
                                   all_attempts, &StudyCellRecord::cell, cells));
    RETURN_IF_ERROR(ReadStudyTable(reader_, "study_references", study::ReferenceFields(),
                                   sweep_id, all_attempts, &StudyReferenceRecord::reference,
                                   references));
    return absl::OkStatus();
  }();
  (void)reader_.Exec("COMMIT");
  return status;
}


}  // namespace totalgrad::storage
