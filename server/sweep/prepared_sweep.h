// A sweep spec as a coordinator stores it: canonical, checked job by job,
// counted and hashed. The one preparation behind a submission (the
// coordinator's SubmitSweep, server/service/submission.h) and the CLI's dry
// run without a coordinator, so both count the same jobs and print the same
// hash. The jobs themselves are not kept: ForEachJob expands them again, one
// at a time, when they are stored (a submission of 100,000 jobs held about
// 480 MB as a vector; issue 28 item 3).
#ifndef TOTALGRAD_SERVER_SWEEP_PREPARED_SWEEP_H_
#define TOTALGRAD_SERVER_SWEEP_PREPARED_SWEEP_H_

#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "absl/status/statusor.h"
#include "server/sweep/sweep_spec.h"

namespace totalgrad::sweep {

struct PreparedSweep {
  SweepSpec spec;  // canonical (CanonicalizeSpec)
  std::string canonical_json;
  std::string spec_hash;
  // The hash builds that kept [protocol] in file order gave the same sweep,
  // when it differs (so a resubmission of a sweep they stored is the same).
  std::vector<std::string> equivalent_spec_hashes;
  int64_t jobs_total = 0;         // trial jobs and study jobs
  int64_t episodes_expected = 0;  // summed over the jobs

  // The spec's jobs in ordinal order (ForEachExpandedJob on `spec`), the
  // same every call. Every job was checked by PrepareSweep, so an error is
  // `visit`'s own.
  absl::Status ForEachJob(const std::function<absl::Status(ExpandedJob&&)>& visit) const;
};

// Canonicalizes, checks every job (expanding them once without keeping them),
// counts and hashes. InvalidArgument naming the field or grid point at fault
// (CanonicalizeSpec, ForEachExpandedJob).
absl::StatusOr<PreparedSweep> PrepareSweep(SweepSpec spec);

}  // namespace totalgrad::sweep

#endif  // TOTALGRAD_SERVER_SWEEP_PREPARED_SWEEP_H_
