// The field tables (core/common/record.h) of the service's own records: a
// job (storage::JobRecord, `totalgrad job list`, the dashboard's jobs), a
// sweep summary (storage::SweepRecord, `totalgrad sweep list|status`, the
// dashboard's sweeps) and an archived attempt (storage::ImportedAttempt, the
// `attempt_log` of a sweep archive). One description per record (issue 13):
// the proto conversion (server/service/convert.cc, by reflection on these
// names into v1::JobInfo, v1::SweepInfo, from v1::AttemptInfo), the CLI's CSV
// and JSON, the dashboard's JSON and the sweep archive's `sweep`, `jobs` and
// `attempt_log` objects (io/record_format.h; server/service/sweep_archive.h,
// written and read) read these tables and name no field.
//
// Contract, beyond record.h's:
//   * a name is the proto field's name (job_id, created_unix_ms), which is
//     therefore also the CSV column and JSON key on every path;
//   * the tables hold what the service shows of a record; the store's own
//     bookkeeping (JobRecord::payload, sweep_id, sweep_state, max_attempts,
//     max_lost_leases, completed_attempt; SweepRecord::id) is not shown and
//     not in them;
//   * JobRecord::options, a list of (key, text) pairs that no field type
//     holds, is not in the table: ToProto/FromProto copy it as repeated
//     TrialOption, the CLI shows it in `job logs` and the sweep archive
//     writes it as its own key `options` ({KEY: TEXT}), beside the job's
//     `completed_attempt` (bookkeeping, above) and `attempt_log`;
//   * ImportedAttemptFields() is the archive's attempt: what the importing
//     store takes (ImportedAttempt; its episodes and study rows are records
//     of their own tables). It is not on storage::AttemptRecord, the store's
//     attempt as ListAttempts reads it: that struct's number sits in a nested
//     LeaseKey, which no member pointer of a table reaches, and it holds
//     lease bookkeeping (lease expiry, episodes_stored, checkpoint_episode)
//     that an archive does not carry. Its names are v1::AttemptInfo's, so
//     the export reads it from the proto by reflection;
//   * state and kind are enumerators written as their stored names
//     ("queued", "lease_lost", "study"; storage::ToString).
// The job and sweep SELECTs are not generated from these tables: their
// values are computed (counts, the latest attempt's worker) by joins, not
// read from columns of one table (docs/core.md "Records").
//
// Thread safety: the tables are built once (function-local statics) and
// read-only after.
#ifndef TOTALGRAD_SERVER_STORAGE_SERVICE_RECORDS_H_
#define TOTALGRAD_SERVER_STORAGE_SERVICE_RECORDS_H_

#include "core/common/record.h"
#include "server/storage/store.h"

namespace totalgrad::storage {

const record::FieldTable<JobRecord>& JobFields();
const record::FieldTable<SweepRecord>& SweepFields();
const record::FieldTable<ImportedAttempt>& ImportedAttemptFields();

}  // namespace totalgrad::storage

#endif  // TOTALGRAD_SERVER_STORAGE_SERVICE_RECORDS_H_
