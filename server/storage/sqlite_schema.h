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
#include <string>

#include "absl/status/status.h"
#include "server/storage/sqlite_db.h"

namespace totalgrad::storage::internal {

// Version 4: job_options, episodes.cpu_seconds, the views, meta filled.
// Version 5: jobs.seed is an INTEGER column (was TEXT).
// Version 6: study_references.agreement_resolution.
// Version 7: episodes.held_fraction. Version 8: the estimator statistics.
// Version 9: the views carry every option and the exports' column names.
inline constexpr int kSchemaVersion = 9;

// The schema of version 1 (a new database is created as version 1 and
// migrated, in one transaction, so new and migrated files are alike).
const char* SchemaText();

// Applies the migrations from `from` up to kSchemaVersion inside the
// caller's transaction and sets user_version and the meta table. The caller
// turns foreign_keys OFF before its transaction (version 5 rebuilds the jobs
// table, which other tables reference) and back ON after; Migrate checks
// every key itself before returning (DataLoss naming a dangling row).
absl::Status Migrate(Db& db, int64_t from);

// Stores a job's swept keys (method, seed and the variant's "key=value"
// pairs) in job_options, numbers also as numbers.
absl::Status WriteJobOptions(Db& db, int64_t job_id, const std::string& method,
                             const std::string& seed, const std::string& variant);

// The view "episodes/<sweep name>": one row per stored episode of the sweep
// with the columns of `results export -f csv` in its order (the job's
// coordinates and outcome, every trial option typed, the episode's record)
// and then worker_build and wall_seconds (optimisation_seconds' old name).
// Swept options are read per row from job_options; the others, the sweep's
// protocol, are constants from its first trial job. (Re)created when the
// sweep is created or grown.
std::string SweepViewName(const std::string& sweep_name);
absl::Status CreateSweepView(Db& db, int64_t sweep_id, const std::string& sweep_name);
absl::Status DropSweepView(Db& db, const std::string& sweep_name);

}  // namespace totalgrad::storage::internal

#endif  // TOTALGRAD_SERVER_STORAGE_SQLITE_SCHEMA_H_
