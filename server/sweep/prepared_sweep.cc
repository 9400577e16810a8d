#include "server/sweep/prepared_sweep.h"

#include <utility>

namespace totalgrad::sweep {

int64_t PreparedSweep::episodes_expected() const {
  int64_t episodes = 0;
  for (const ExpandedJob& job : jobs) episodes += job.episodes_expected;
  return episodes;
}

absl::StatusOr<PreparedSweep> PrepareSweep(SweepSpec spec) {
  std::vector<std::string> protocol_order;
  for (const auto& [key, value] : spec.protocol) protocol_order.push_back(key);
  absl::Status status = CanonicalizeSpec(&spec);
  if (!status.ok()) return status;
  absl::StatusOr<std::vector<ExpandedJob>> jobs = ExpandJobs(spec);
  if (!jobs.ok()) return jobs.status();
  PreparedSweep prepared;
  prepared.jobs = *std::move(jobs);
  prepared.canonical_json = CanonicalJson(spec);
  prepared.spec_hash = SpecHash(spec);
  const std::string legacy_hash = LegacySpecHash(spec, protocol_order);
  if (legacy_hash != prepared.spec_hash) prepared.equivalent_spec_hashes.push_back(legacy_hash);
  prepared.spec = std::move(spec);
  return prepared;
}

}  // namespace totalgrad::sweep
