#include "server/storage/job_kinds.h"

#include "absl/strings/str_cat.h"
#include "absl/strings/str_join.h"

namespace totalgrad::storage {
namespace {

// The result tables, in the order of ResultTotals' members. The index
// columns are the tables' primary keys after (job_id, attempt)
// (sqlite_schema.cc).
enum TableIndex { kEpisodes, kStudyCells, kStudyReferences };

}  // namespace

const std::vector<ResultTable>& ResultTables() {
  static const auto* const tables = new std::vector<ResultTable>{
      {"episodes", "episode", "episodes",
       [](const JobResults& r) { return r.episodes.size(); }, &ResultTotals::episodes},
      {"study_cells", "idx", "study_cells rows",
       [](const JobResults& r) { return r.study.cells.size(); }, &ResultTotals::study_cells},
      {"study_references", "idx", "study_references rows",
       [](const JobResults& r) { return r.study.references.size(); },
       &ResultTotals::study_references},
  };
  return *tables;
}

const std::vector<JobKindInfo>& JobKinds() {
  static const auto* const kinds = [] {
    const std::vector<ResultTable>& t = ResultTables();
    return new std::vector<JobKindInfo>{
        // A trial reports one row per episode as it finishes; it is complete
        // with every episode the job was submitted with. It checkpoints after
        // each episode and its last evaluation is its verdict.
        {JobKind::kTrial, "trial", {&t[kEpisodes]}, CompletionRule::kJobExpected,
         /*checkpoints=*/true, /*reports_verdict=*/true},
        // A study (core/study) reports its cells and reference gradients when
        // it ends; only the worker knows how many there are.
        {JobKind::kStudy, "study", {&t[kStudyCells], &t[kStudyReferences]},
         CompletionRule::kReported, /*checkpoints=*/false, /*reports_verdict=*/false},
    };
  }();
  return *kinds;
}

const JobKindInfo& KindInfo(JobKind kind) {
  for (const JobKindInfo& info : JobKinds()) {
    if (info.kind == kind) return info;
  }
  // Every enumerator has a row (JobKindsTest.EveryKindHasOneRow).
  return JobKinds().front();
}

std::optional<JobKind> ParseJobKind(absl::string_view name) {
  for (const JobKindInfo& info : JobKinds()) {
    if (info.name == name) return info.kind;
  }
  return std::nullopt;
}

bool Owns(const JobKindInfo& kind, const ResultTable& table) {
  for (const ResultTable* owned : kind.tables) {
    if (owned == &table) return true;
  }
  return false;
}

const JobKindInfo& OwnerOf(const ResultTable& table) {
  for (const JobKindInfo& info : JobKinds()) {
    if (Owns(info, table)) return info;
  }
  return JobKinds().front();  // every table has an owner (JobKindsTest)
}

absl::Status CheckOwnedTables(const JobKindInfo& kind, int64_t job_id, const JobResults& results,
                              const ResultTotals* totals) {
  for (const ResultTable& table : ResultTables()) {
    if (Owns(kind, table)) continue;
    if (table.rows(results) == 0 && (totals == nullptr || totals->*table.total == 0)) continue;
    std::vector<absl::string_view> owned;
    for (const ResultTable* t : kind.tables) owned.push_back(t->name);
    return absl::InvalidArgumentError(absl::StrCat(
        "job ", job_id, " is a ", kind.name, " job; table ", table.name, " belongs to ",
        OwnerOf(table).name, " jobs (a ", kind.name, " job reports ", absl::StrJoin(owned, ", "),
        ")"));
  }
  return absl::OkStatus();
}

absl::StatusOr<ResultTotals> RequiredRows(const JobKindInfo& kind, const LeaseKey& key,
                                          int episodes_expected, const ResultTotals& reported) {
  if (absl::Status owned = CheckOwnedTables(kind, key.job_id, JobResults{}, &reported);
      !owned.ok()) {
    return owned;
  }
  ResultTotals required;
  for (const ResultTable* table : kind.tables) {
    const int total = reported.*table->total;
    switch (kind.rule) {
      case CompletionRule::kJobExpected:
        // The job's own expected count decides, never the worker's.
        if (total != episodes_expected) {
          return absl::InvalidArgumentError(absl::StrCat(
              "completion of job ", key.job_id, " attempt ", key.attempt, " reports ", total, " ",
              table->noun, "; the job expects ", episodes_expected, " (", table->noun, " 0..",
              episodes_expected - 1, ")"));
        }
        required.*table->total = episodes_expected;
        break;
      case CompletionRule::kReported:
        if (total < 1 || total > kMaxRowsPerTable) {
          return absl::InvalidArgumentError(absl::StrCat(
              "completion of ", kind.name, " job ", key.job_id, " reports ", total, " ",
              table->noun, "; a ", kind.name, " job has between 1 and ", kMaxRowsPerTable,
              " of each of its tables"));
        }
        required.*table->total = total;
        break;
    }
  }
  return required;
}

absl::Status MissingRowsError(const ResultTable& table, const LeaseKey& key,
                              const std::vector<int>& missing, int total) {
  return absl::FailedPreconditionError(absl::StrCat(
      "cannot complete job ", key.job_id, " attempt ", key.attempt, ": ", table.noun, " ",
      absl::StrJoin(missing, ","), " of 0..", total - 1, " are not stored"));
}

}  // namespace totalgrad::storage
