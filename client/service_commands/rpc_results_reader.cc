#include "client/service_commands/rpc_results_reader.h"

#include <map>

#include "absl/status/status.h"
#include "absl/strings/str_cat.h"
#include "client/service_commands/streamed_reads.h"
#include "runtime/record_proto.h"

namespace totalgrad::cli {

absl::StatusOr<std::vector<results::CompletedTrial>> RpcResultsReader::CompletedTrials(
    const std::string& sweep) {
  // Results first, so every job they name is already completed when the
  // jobs are listed.
  v1::ListTrialResultsResponse completed;
  grpc::Status status = FetchTrialResults(connection_, sweep, &completed);
  if (!status.ok()) return ToAbslStatus(status);
  last_sweep_ = completed.sweep();
  std::map<int64_t, record::TextPairs> options_of;
  v1::ListJobsRequest jobs_request;
  jobs_request.set_sweep_name(sweep);
  jobs_request.add_states(v1::JOB_STATE_COMPLETED);
  status = ForEachJobPage(connection_, jobs_request, [&](const v1::ListJobsResponse& jobs) {
    for (const v1::JobInfo& job : jobs.jobs()) {
      record::TextPairs& options = options_of[job.job_id()];
      for (const auto& option : job.options()) options.emplace_back(option.key(), option.value());
    }
    return grpc::Status::OK;
  });
  if (!status.ok()) return ToAbslStatus(status);
  std::vector<results::CompletedTrial> trials;
  trials.reserve(completed.results_size());
  for (const v1::TrialResult& result : completed.results()) {
    results::CompletedTrial& trial = trials.emplace_back();
    record_proto::RecordFromProto(results::CompletedTrialResultFields(), result, &trial);
    trial.sweep = sweep;
  }
  if (absl::Status attached = results::AttachOptions(sweep, std::move(options_of), &trials);
      !attached.ok()) {
    return attached;
  }
  return trials;
}

}  // namespace totalgrad::cli
