// The options an archived trial ran with, in this build's terms: the import
// stores them where this build would give the job others, so that a trial's
// stored options always say what ran (storage::ImportedJob::options_as_run).
#ifndef TOTALGRAD_SERVER_SERVICE_OPTIONS_AS_RUN_H_
#define TOTALGRAD_SERVER_SERVICE_OPTIONS_AS_RUN_H_

#include "absl/status/status.h"
#include "server/storage/store_records.h"

namespace totalgrad::service {

// For a completed trial job whose archive lists its options: sets
// job->options_as_run to every key of this build's trial option table, the
// archive's values where it has the key and, where it lacks one (an option
// added after the archive's build), the value the computation had before
// the option existed (learner::TrialOptionsFromStoredPairs: e.g.
// gp_variance_tolerance 0, the exact variance). Other jobs are left as they
// are. InvalidArgument naming the job when its options do not read (a key
// or value this build does not know: an archive of a newer build).
absl::Status SetOptionsAsRun(storage::ImportedJob* job);

}  // namespace totalgrad::service

#endif  // TOTALGRAD_SERVER_SERVICE_OPTIONS_AS_RUN_H_
