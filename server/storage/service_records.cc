#include "server/storage/service_records.h"

#include <string>

#include "server/storage/job_kinds.h"

namespace totalgrad::storage {
namespace {

// The enumerators as text, one pair per (record, member): record.h's
// EnumText holds plain function pointers.
std::string JobStateText(const JobRecord& j) { return std::string(ToString(j.state)); }
bool ParseJobStateInto(const std::string& text, JobRecord* j) {
  const std::optional<JobState> state = ParseJobState(text);
  if (state) j->state = *state;
  return state.has_value();
}
std::string JobKindText(const JobRecord& j) { return std::string(ToString(j.kind)); }
bool ParseJobKindInto(const std::string& text, JobRecord* j) {
  const std::optional<JobKind> kind = ParseJobKind(text);
  if (kind) j->kind = *kind;
  return kind.has_value();
}
std::string SweepStateText(const SweepRecord& s) { return std::string(ToString(s.state)); }
bool ParseSweepStateInto(const std::string& text, SweepRecord* s) {
  const std::optional<SweepState> state = ParseSweepState(text);
  if (state) s->state = *state;
  return state.has_value();
}
bool SweepFinished(const SweepRecord& s) { return s.finished(); }
std::string SweepStateOfJobText(const JobRecord& j) { return std::string(ToString(j.sweep_state)); }
bool ParseSweepStateOfJobInto(const std::string& text, JobRecord* j) {
  const std::optional<SweepState> state = ParseSweepState(text);
  if (state) j->sweep_state = *state;
  return state.has_value();
}
std::string AttemptStateText(const ImportedAttempt& a) { return std::string(ToString(a.state)); }
bool ParseAttemptStateInto(const std::string& text, ImportedAttempt* a) {
  const std::optional<AttemptState> state = ParseAttemptState(text);
  if (state) a->state = *state;
  return state.has_value();
}

}  // namespace

// The order is the CSV's and the JSON's: what identifies the job, what it
// runs, its progress, its verdict, and the error text last (long).
const record::FieldTable<JobRecord>& JobFields() {
  static const record::FieldTable<JobRecord> table = {
      {"job_id", &JobRecord::id},
      {"sweep_name", &JobRecord::sweep_name},
      {"kind", record::EnumText<JobRecord>{&JobKindText, &ParseJobKindInto}},
      {"ordinal", &JobRecord::ordinal},
      {"method", &JobRecord::method},
      {"seed", &JobRecord::seed},
      {"variant", &JobRecord::variant},
      {"options", &JobRecord::options},
      {"state", record::EnumText<JobRecord>{&JobStateText, &ParseJobStateInto}},
      {"attempts", &JobRecord::attempts},
      {"failures", &JobRecord::failures},
      {"lost_leases", &JobRecord::lost_leases},
      {"episodes_stored", &JobRecord::episodes_stored},
      {"episodes_expected", &JobRecord::episodes_expected},
      {"worker_id", &JobRecord::worker_id},
      {"success", &JobRecord::success},
      {"final_eval_cost", &JobRecord::final_eval_cost},
      {"last_error", &JobRecord::last_error},
  };
  return table;
}

// The canonical spec (the whole sweep as JSON) is JSON-only: no spreadsheet
// column for it.
const record::FieldTable<SweepRecord>& SweepFields() {
  static const record::FieldTable<SweepRecord> table = {
      {"name", &SweepRecord::name},
      {"description", &SweepRecord::description},
      {"state", record::EnumText<SweepRecord>{&SweepStateText, &ParseSweepStateInto}},
      {"finished", &SweepFinished},
      {"jobs_total", &SweepRecord::jobs_total},
      {"jobs_queued", &SweepRecord::jobs_queued},
      {"jobs_running", &SweepRecord::jobs_running},
      {"jobs_completed", &SweepRecord::jobs_completed},
      {"jobs_failed", &SweepRecord::jobs_failed},
      {"jobs_cancelled", &SweepRecord::jobs_cancelled},
      {"episodes_stored", &SweepRecord::episodes_stored},
      {"episodes_expected", &SweepRecord::episodes_expected},
      {"created_unix_ms", &SweepRecord::created_ms},
      {"spec_hash", &SweepRecord::spec_hash},
      {"source_name", &SweepRecord::source_name},
      {"coordinator_build", &SweepRecord::coordinator_build},
      {"max_attempts", &SweepRecord::max_attempts},
      {"max_lost_leases", &SweepRecord::max_lost_leases},
      {"max_concurrent", &SweepRecord::max_concurrent},
      {"canonical_spec", &SweepRecord::canonical_spec, /*csv=*/false},
  };
  return table;
}

const record::FieldTable<JobRecord>& JobStoreOnlyFields() {
  static const record::FieldTable<JobRecord> table = {
      {"sweep_id", &JobRecord::sweep_id},
      {"sweep_state",
       record::EnumText<JobRecord>{&SweepStateOfJobText, &ParseSweepStateOfJobInto}},
      {"max_attempts", &JobRecord::max_attempts},
      {"max_lost_leases", &JobRecord::max_lost_leases},
      {"completed_attempt", &JobRecord::completed_attempt},
      {"payload", &JobRecord::payload},
  };
  return table;
}

const record::FieldTable<SweepRecord>& SweepStoreOnlyFields() {
  static const record::FieldTable<SweepRecord> table = {
      {"id", &SweepRecord::id},
  };
  return table;
}

// The order is v1::AttemptInfo's: which attempt, how it ended, where and
// when it ran, its error.
const record::FieldTable<ImportedAttempt>& ImportedAttemptFields() {
  static const record::FieldTable<ImportedAttempt> table = {
      {"attempt", &ImportedAttempt::attempt},
      {"state", record::EnumText<ImportedAttempt>{&AttemptStateText, &ParseAttemptStateInto}},
      {"worker_id", &ImportedAttempt::worker_id},
      {"worker_host", &ImportedAttempt::worker_host},
      {"worker_build", &ImportedAttempt::worker_build},
      {"started_unix_ms", &ImportedAttempt::started_ms},
      {"ended_unix_ms", &ImportedAttempt::ended_ms},
      {"error", &ImportedAttempt::error},
  };
  return table;
}

}  // namespace totalgrad::storage
