// Job kinds as data (issue 13): what each kind of job reports and when one of
// its attempts is complete.
//
// A kind owns result tables (each a SQL table of rows keyed within an attempt
// by an index column) and a completion rule: how many rows of each table a
// completed attempt must hold, all of 0..total-1. The store and the
// scheduler have one path for every kind and read this table wherever kinds
// differ: storing results (rows of a table the kind does not own are
// refused, naming the kind and the table), the completion check (one
// missing-rows query per table, sqlite_internal.h MissingRows),
// checkpoints, and whether the worker's verdict is the job's.
//
// Adding a kind: docs/core.md, "Where to add what", "A new job kind".
#ifndef TOTALGRAD_SERVER_STORAGE_JOB_KINDS_H_
#define TOTALGRAD_SERVER_STORAGE_JOB_KINDS_H_

#include <cstddef>
#include <cstdint>
#include <optional>
#include <vector>

#include "absl/status/status.h"
#include "absl/status/statusor.h"
#include "absl/strings/string_view.h"
#include "server/storage/store.h"

namespace totalgrad::storage {

// Most rows a completion may report for one table (a forged total is refused
// before the store counts up to it).
inline constexpr int kMaxRowsPerTable = 1000000;

// One table of result rows.
struct ResultTable {
  absl::string_view name;          // the SQL table, e.g. "episodes"
  absl::string_view index_column;  // the row's key within an attempt
  absl::string_view noun;          // in messages: "episodes", "study_cells rows"
  // How many rows of this table a bundle holds, and its member of ResultTotals.
  size_t (*rows)(const JobResults&) = nullptr;
  int ResultTotals::*total = nullptr;
};

// Where the number of rows a completed attempt must hold comes from.
enum class CompletionRule {
  // The job's own episodes_expected (fixed at submission); the worker's
  // reported total must equal it. A completion reporting fewer would count
  // a trial with rows missing (docs/results_schema.md promises all of them).
  kJobExpected,
  // The worker's reported totals (the job cannot know them in advance, e.g.
  // a study's cells), each between 1 and kMaxRowsPerTable.
  kReported,
};

struct JobKindInfo {
  JobKind kind = JobKind::kTrial;
  absl::string_view name;  // as stored in jobs.kind and shown to users
  std::vector<const ResultTable*> tables;
  CompletionRule rule = CompletionRule::kJobExpected;
  // Attempts may store a checkpoint (the state a later attempt resumes from).
  bool checkpoints = false;
  // The worker's success and final_eval_cost (finite) are the job's verdict;
  // without one a completed job is a success with no cost (NaN): its
  // numbers are in its rows.
  bool reports_verdict = false;
};

// Every result table, of every kind (episodes, study_cells, study_references).
const std::vector<ResultTable>& ResultTables();
// Every kind, in enum order.
const std::vector<JobKindInfo>& JobKinds();
const JobKindInfo& KindInfo(JobKind kind);
// The kind named `name` (jobs.kind); nullopt for an unknown name.
std::optional<JobKind> ParseJobKind(absl::string_view name);
bool Owns(const JobKindInfo& kind, const ResultTable& table);
// The kind that owns `table`.
const JobKindInfo& OwnerOf(const ResultTable& table);

// InvalidArgument naming the job's kind and the table when `results` holds
// rows (or, if given, `totals` a non-zero total) of a table `kind` does not
// own, e.g. "job 3 is a study job; table episodes belongs to trial jobs".
absl::Status CheckOwnedTables(const JobKindInfo& kind, int64_t job_id, const JobResults& results,
                              const ResultTotals* totals = nullptr);

// The completion rule: how many rows of each of the kind's tables attempt
// `key` must hold (all of 0..n-1), given the job's `episodes_expected` and
// the totals the worker reported. InvalidArgument (nothing is stored by the
// caller): a total of a table the kind does not own; under kJobExpected a
// reported total other than the job's; under kReported a total outside
// 1..kMaxRowsPerTable.
absl::StatusOr<ResultTotals> RequiredRows(const JobKindInfo& kind, const LeaseKey& key,
                                          int episodes_expected, const ResultTotals& reported);

// The jobs.episodes_expected column: the job's expected count for a kind
// whose completion rule is kJobExpected; 1 for the others (the column's
// CHECK wants >= 1; they have no count of their own), read back as 0.
inline int64_t EpisodesExpectedColumn(const JobKindInfo& kind, int64_t episodes_expected) {
  return kind.rule == CompletionRule::kJobExpected ? episodes_expected : 1;
}
inline int64_t ExpectedEpisodes(const JobKindInfo& kind, int64_t column) {
  return kind.rule == CompletionRule::kJobExpected ? column : 0;
}

// FailedPrecondition for rows `missing` of 0..total-1 of `table`: "cannot
// complete job 4 attempt 1: episodes 1,2 of 0..3 are not stored".
absl::Status MissingRowsError(const ResultTable& table, const LeaseKey& key,
                              const std::vector<int>& missing, int total);

}  // namespace totalgrad::storage

#endif  // TOTALGRAD_SERVER_STORAGE_JOB_KINDS_H_
