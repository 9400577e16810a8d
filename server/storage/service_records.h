// The field tables (core/common/record.h) of the service's own records: a
// job (storage::JobRecord, `totalgrad job list`, the dashboard's jobs) and a
// sweep summary (storage::SweepRecord, `totalgrad sweep list|status`, the
// dashboard's sweeps). One description per record (issue 13): the proto
// conversion (server/service/convert.cc, by reflection on these names into
// v1::JobInfo and v1::SweepInfo), the CLI's CSV and JSON and the dashboard's
// JSON (io/record_format.h) read these tables and name no field.
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
//     TrialOption, and the CLI shows it in `job logs`;
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

}  // namespace totalgrad::storage

#endif  // TOTALGRAD_SERVER_STORAGE_SERVICE_RECORDS_H_
