// A sweep spec as a coordinator stores it: canonical, expanded into its jobs
// and hashed. The one preparation behind a submission (the coordinator's
// SubmitSweep, server/service/submission.h) and the CLI's dry run without a
// coordinator, so both count the same jobs and print the same hash.
#ifndef TOTALGRAD_SERVER_SWEEP_PREPARED_SWEEP_H_
#define TOTALGRAD_SERVER_SWEEP_PREPARED_SWEEP_H_

#include <cstdint>
#include <string>
#include <vector>

#include "absl/status/statusor.h"
#include "server/sweep/sweep_spec.h"

namespace totalgrad::sweep {

struct PreparedSweep {
  SweepSpec spec;  // canonical (CanonicalizeSpec)
  std::vector<ExpandedJob> jobs;
  std::string canonical_json;
  std::string spec_hash;
  // The hash builds that kept [protocol] in file order gave the same sweep,
  // when it differs (so a resubmission of a sweep they stored is the same).
  std::vector<std::string> equivalent_spec_hashes;
  int64_t episodes_expected() const;
};

// InvalidArgument naming the field at fault (CanonicalizeSpec, ExpandJobs).
absl::StatusOr<PreparedSweep> PrepareSweep(SweepSpec spec);

}  // namespace totalgrad::sweep

#endif  // TOTALGRAD_SERVER_SWEEP_PREPARED_SWEEP_H_
