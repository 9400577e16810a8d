// Test helper: turns a database of this build's schema back into an older
// version's columns, so that the migration tests start from what an older
// coordinator wrote. Header only; tests only.
#ifndef TOTALGRAD_TESTS_SERVICE_SCHEMA_DOWNGRADE_H_
#define TOTALGRAD_TESTS_SERVICE_SCHEMA_DOWNGRADE_H_

#include <string>
#include <utility>
#include <vector>

#include "absl/status/status.h"
#include "absl/strings/str_cat.h"
#include "server/storage/sqlite_db.h"
#include "server/storage/sqlite_internal.h"

namespace totalgrad::testing {

// Drops every view (they read the columns; Migrate recreates them) and the
// columns that schema versions after `version` added (version 7: the rollout
// verdict and attempt origins; version 8: the optimisation diagnostics;
// version 10: a sweep's shared trial options, each job's whole list written
// back first, as an older coordinator stored it).
inline absl::Status DropColumnsAddedAfter(storage::internal::Db& db, int version) {
  std::vector<std::string> views;
  {
    absl::StatusOr<storage::internal::Statement> list = storage::internal::Statement::Prepare(
        db, "SELECT name FROM sqlite_schema WHERE type = 'view'");
    if (!list.ok()) return list.status();
    for (;;) {
      absl::StatusOr<bool> row = list->Step();
      if (!row.ok()) return row.status();
      if (!*row) break;
      views.push_back(list->ColumnText(0));
    }
  }
  for (const std::string& view : views) {
    if (absl::Status s = db.Exec(absl::StrCat("DROP VIEW \"", view, "\"")); !s.ok()) return s;
  }
  const std::vector<std::pair<int, std::string>> added = {
      {7, "ALTER TABLE episodes DROP COLUMN held_fraction"},
      {7, "ALTER TABLE attempts DROP COLUMN origin"},
      {8, "ALTER TABLE episodes DROP COLUMN gradient_norm_first"},
      {8, "ALTER TABLE episodes DROP COLUMN gradient_norm_middle"},
      {8, "ALTER TABLE episodes DROP COLUMN gradient_norm_last"},
      {8, "ALTER TABLE episodes DROP COLUMN gradient_norm_mean"},
      {8, "ALTER TABLE episodes DROP COLUMN gradient_snr_first"},
      {8, "ALTER TABLE episodes DROP COLUMN gradient_snr_middle"},
      {8, "ALTER TABLE episodes DROP COLUMN gradient_snr_last"},
      {8, "ALTER TABLE episodes DROP COLUMN gradient_snr_mean"},
      {8, "ALTER TABLE episodes DROP COLUMN step_norm_first"},
      {8, "ALTER TABLE episodes DROP COLUMN step_norm_middle"},
      {8, "ALTER TABLE episodes DROP COLUMN step_norm_last"},
      {8, "ALTER TABLE episodes DROP COLUMN step_norm_mean"},
      {8, "ALTER TABLE episodes DROP COLUMN ess_min"},
      {8, "ALTER TABLE episodes DROP COLUMN ess_median"},
      {8, "ALTER TABLE episodes DROP COLUMN ess_low_fraction"},
      {8, "ALTER TABLE episodes DROP COLUMN lr_share_json"},
      {10, absl::StrCat("UPDATE jobs AS j SET options_json = ",
                        storage::internal::JobOptionsJsonSql(),
                        " WHERE j.options_json = '' AND j.kind = 'trial'")},
      {10, "ALTER TABLE sweeps DROP COLUMN trial_options_json"},
  };
  for (const auto& [since, sql] : added) {
    if (since <= version) continue;
    if (absl::Status s = db.Exec(sql); !s.ok()) return s;
  }
  return absl::OkStatus();
}

}  // namespace totalgrad::testing

#endif  // TOTALGRAD_TESTS_SERVICE_SCHEMA_DOWNGRADE_H_
