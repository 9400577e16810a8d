// The results library's read interface (results/completed_trial.h) over a
// coordinator's ControlService: what `results table`, `results compare` and
// `results table1` compute from, the same records the dashboard reads from
// the store (server/storage/store_results_reader.h). With --db the
// connection is the service handlers over the database file, so this reads
// that file the same way.
#ifndef TOTALGRAD_CLIENT_SERVICE_COMMANDS_RPC_RESULTS_READER_H_
#define TOTALGRAD_CLIENT_SERVICE_COMMANDS_RPC_RESULTS_READER_H_

#include <string>
#include <vector>

#include "client/service_commands/connection.h"
#include "results/completed_trial.h"

namespace totalgrad::cli {

// Not thread-safe (one connection's calls). Does not own the connection.
class RpcResultsReader : public results::ResultsReader {
 public:
  explicit RpcResultsReader(Connection* connection) : connection_(connection) {}

  // ListTrialResults (the counting attempts) joined with the options of the
  // sweep's completed jobs (ListJobs, page by page). The gRPC status's code
  // and message on failure; Internal when a result names a job that is not
  // listed completed.
  absl::StatusOr<std::vector<results::CompletedTrial>> CompletedTrials(
      const std::string& sweep) override;

  // The sweep as the last CompletedTrials call saw it (job counts for
  // headers such as "12 of 40 jobs completed").
  const v1::SweepInfo& last_sweep() const { return last_sweep_; }

 private:
  Connection* connection_;
  v1::SweepInfo last_sweep_;
};

}  // namespace totalgrad::cli

#endif  // TOTALGRAD_CLIENT_SERVICE_COMMANDS_RPC_RESULTS_READER_H_
