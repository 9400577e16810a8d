// The results library's read interface (results/completed_trial.h) over a
// Store: what the dashboard and any coordinator-side reader compute their
// numbers from, so they equal the CLI's (which reads the same records over
// gRPC, client/service_commands/rpc_results_reader.h).
#ifndef TOTALGRAD_SERVER_STORAGE_STORE_RESULTS_READER_H_
#define TOTALGRAD_SERVER_STORAGE_STORE_RESULTS_READER_H_

#include <string>
#include <vector>

#include "results/completed_trial.h"
#include "server/storage/store.h"

namespace totalgrad::storage {

// Thread-safe when the store is (SqliteStore is). Does not own the store.
class StoreResultsReader : public results::ResultsReader {
 public:
  explicit StoreResultsReader(StoreReader* store) : store_(store) {}

  // The store's trial results (ListTrialResults: the counting attempts)
  // joined with the options of their completed jobs (ListJobs, page by
  // page); Internal when a result names a job that is not listed completed.
  absl::StatusOr<std::vector<results::CompletedTrial>> CompletedTrials(
      const std::string& sweep) override;

 private:
  StoreReader* store_;
};

}  // namespace totalgrad::storage

#endif  // TOTALGRAD_SERVER_STORAGE_STORE_RESULTS_READER_H_
