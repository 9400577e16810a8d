#include "server/sweep/prepared_sweep.h"

#include <utility>

#include "runtime/status_macros.h"

namespace totalgrad::sweep {

absl::Status PreparedSweep::ForEachJob(
    const std::function<absl::Status(ExpandedJob&&)>& visit) const {
  return ForEachExpandedJob(spec, visit);
}

absl::StatusOr<PreparedSweep> PrepareSweep(SweepSpec spec) {
  std::vector<std::string> protocol_order;
  for (const auto& [key, value] : spec.protocol) protocol_order.push_back(key);
  RETURN_IF_ERROR(CanonicalizeSpec(&spec));
  PreparedSweep prepared;
  RETURN_IF_ERROR(ForEachExpandedJob(spec, [&](ExpandedJob&& job) {
    ++prepared.jobs_total;
    prepared.episodes_expected += job.episodes_expected;
    return absl::OkStatus();
  }));
  prepared.canonical_json = CanonicalJson(spec);
  prepared.spec_hash = SpecHash(spec);
  const std::string legacy_hash = LegacySpecHash(spec, protocol_order);
  if (legacy_hash != prepared.spec_hash) prepared.equivalent_spec_hashes.push_back(legacy_hash);
  prepared.spec = std::move(spec);
  return prepared;
}

}  // namespace totalgrad::sweep
