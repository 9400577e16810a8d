#include "server/storage/service_records.h"

#include <optional>
#include <string>

#include "absl/strings/string_view.h"

#include "server/storage/job_kinds.h"

namespace totalgrad::storage {
namespace {

// An enumerator member as text: storage's ToString for it, and its Parse
// function to set it from a name (false, the record unchanged, for a name
// the enum lacks). Captureless lambdas, as record.h's EnumText holds plain
// function pointers.
template <typename R, typename E, E R::*kMember, std::optional<E> (*kParse)(absl::string_view)>
record::EnumText<R> EnumMember() {
  return {[](const R& r) { return std::string(ToString(r.*kMember)); },
          [](const std::string& text, R* r) {
            const std::optional<E> value = kParse(text);
            if (value) r->*kMember = *value;
            return value.has_value();
          }};
}

bool SweepFinished(const SweepRecord& s) { return s.finished(); }

}  // namespace

// The order is the CSV's and the JSON's: what identifies the job, what it
// runs, its progress, its verdict, and the error text last (long).
const record::FieldTable<JobRecord>& JobFields() {
  static const record::FieldTable<JobRecord> table = {
      {"job_id", &JobRecord::id},
      {"sweep_name", &JobRecord::sweep_name},
      {"kind", EnumMember<JobRecord, JobKind, &JobRecord::kind, &ParseJobKind>()},
      {"ordinal", &JobRecord::ordinal},
      {"method", &JobRecord::method},
      {"seed", &JobRecord::seed},
      {"variant", &JobRecord::variant},
      {"options", &JobRecord::options},
      {"state", EnumMember<JobRecord, JobState, &JobRecord::state, &ParseJobState>()},
      {"attempts", &JobRecord::attempts},
      {"failures", &JobRecord::failures},
      {"lost_leases", &JobRecord::lost_leases},
      {"episodes_stored", &JobRecord::episodes_stored},
      {"episodes_expected", &JobRecord::episodes_expected},
      {"worker_id", &JobRecord::worker_id},
      {"success", &JobRecord::success},
      {"final_eval_cost", &JobRecord::final_eval_cost},
      {"held_fraction", &JobRecord::held_fraction},
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
      {"state", EnumMember<SweepRecord, SweepState, &SweepRecord::state, &ParseSweepState>()},
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
       EnumMember<JobRecord, SweepState, &JobRecord::sweep_state, &ParseSweepState>()},
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
      {"state",
       EnumMember<ImportedAttempt, AttemptState, &ImportedAttempt::state, &ParseAttemptState>()},
      {"worker_id", &ImportedAttempt::worker_id},
      {"worker_host", &ImportedAttempt::worker_host},
      {"worker_build", &ImportedAttempt::worker_build},
      {"started_unix_ms", &ImportedAttempt::started_ms},
      {"ended_unix_ms", &ImportedAttempt::ended_ms},
      {"error", &ImportedAttempt::error},
      {"origin", &ImportedAttempt::origin},
  };
  return table;
}

}  // namespace totalgrad::storage
