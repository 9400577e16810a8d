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
//   * JobFields() and SweepFields() hold what the service shows of a
//     record; the store's own bookkeeping (JobRecord::payload, sweep_id,
//     sweep_state, max_attempts, max_lost_leases, completed_attempt;
//     SweepRecord::id) is not shown: it is in the *StoreOnlyFields() tables,
//     which only the store reads;
//   * a job's options are (key, text) pairs (record::TextPairs): repeated
//     TrialOption in the proto, [[key, text], ...] in JSON, key=text;... in
//     CSV;
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
// The store's SELECTs are generated from these tables too
// (sqlite_records.h MakeSqlView): the store says, per field name, which SQL
// expression reads it (a column, a join, a count), and a field it does not
// place is an abort in the first test that lists a record.
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
const record::FieldTable<JobRecord>& JobStoreOnlyFields();
const record::FieldTable<SweepRecord>& SweepStoreOnlyFields();
const record::FieldTable<ImportedAttempt>& ImportedAttemptFields();

}  // namespace totalgrad::storage

#endif  // TOTALGRAD_SERVER_STORAGE_SERVICE_RECORDS_H_
