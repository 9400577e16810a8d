// The coordinator database's schema and its migrations, and the parts of the
// schema that follow the data (typed job options, the per-sweep views),
// internal to server/storage. docs/results_schema.md documents every table
// and view.
//
// Threading: as internal::Db (callers hold the store's write mutex and an
// open write transaction for every function here but SchemaText).
#ifndef TOTALGRAD_SERVER_STORAGE_SQLITE_SCHEMA_H_
#define TOTALGRAD_SERVER_STORAGE_SQLITE_SCHEMA_H_

#include <cstdint>
#include <optional>
#include <string>

#include "absl/status/status.h"
#include "core/common/option_pairs.h"
#include "server/storage/sqlite_db.h"

namespace totalgrad::storage::internal {

// Version 4: job_options, episodes.cpu_seconds, the views, meta filled.
// Version 5: jobs.seed is an INTEGER column (was TEXT).
// Version 6: study_references.agreement_resolution.
// Version 7: episodes.held_fraction. Version 8: the estimator statistics.
// Version 9: the views carry every option and the exports' column names.
// Version 10: sweeps.trial_options_json (a sweep's shared trial options,
// once), jobs.options_json '' for a trial job that uses them, the view
// job_option_lists; the views lose wall_seconds (kept for version 9 only).
inline constexpr int kSchemaVersion = 10;

// The schema of version 1 (a new database is created as version 1 and
// migrated, in one transaction, so new and migrated files are alike).
const char* SchemaText();

// Applies the migrations from `from` up to kSchemaVersion inside the
// caller's transaction and sets user_version and the meta table. The caller
// turns foreign_keys OFF before its transaction (version 5 rebuilds the jobs
// table, which other tables reference) and back ON after; Migrate checks
// every key itself before returning (DataLoss naming a dangling row).
absl::Status Migrate(Db& db, int64_t from);

// A job's swept keys and their values: method, seed and the variant's
// "key=value" pairs, in that order (what job_options holds for the job).
OptionPairs JobOptionPairs(const std::string& method, const std::string& seed,
                           const std::string& variant);

// Stores a job's swept keys (method, seed and the variant's "key=value"
// pairs) in job_options, numbers also as numbers.
absl::Status WriteJobOptions(Db& db, int64_t job_id, const std::string& method,
                             const std::string& seed, const std::string& variant);

// A value's number, when its canonical text is one: integers (seeds,
// counts) as INTEGER, finite others as REAL; otherwise neither is set.
// The one typing rule of job_options.number and the views' protocol columns.
struct TextNumber {
  std::optional<int64_t> integer;
  std::optional<double> real;
};
TextNumber ParseTextNumber(const std::string& text);

// The views (sqlite_views.cc). DropViews drops every one of them;
// RecreateViews drops and creates them again from the tables as they are
// (after a column of theirs was added, or the tables they read were rebuilt).
absl::Status DropViews(Db& db);
absl::Status RecreateViews(Db& db);

// The view "episodes/<sweep name>": one row per stored episode of the sweep
// with the columns of `results export -f csv` in its order (the job's
// coordinates and outcome, every trial option typed, the episode's record)
// and then worker_build.
// Swept options are read per row from job_options; the others, the sweep's
// protocol, are constants from its first trial job. (Re)created when the
// sweep is created or grown.
std::string SweepViewName(const std::string& sweep_name);
absl::Status CreateSweepView(Db& db, int64_t sweep_id, const std::string& sweep_name);
absl::Status DropSweepView(Db& db, const std::string& sweep_name);

}  // namespace totalgrad::storage::internal

#endif  // TOTALGRAD_SERVER_STORAGE_SQLITE_SCHEMA_H_
