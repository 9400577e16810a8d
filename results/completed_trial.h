// One completed trial as every reader of results sees it, and the one
// interface through which the results library reads them.
//
// A completed trial is the counting attempt of a completed trial job (the
// superseding attempt where `job supersede` recorded one): its verdict, its
// final evaluation cost, its rollout verdict and its job's options. The
// success table, the method comparisons and Table 1 (stats.h,
// comparison.h, table1.h) are computed from these records only, so the CLI
// (over gRPC), the dashboard and ControlService (over the store) and the
// Python module give the same numbers from the same code.
#ifndef TOTALGRAD_RESULTS_COMPLETED_TRIAL_H_
#define TOTALGRAD_RESULTS_COMPLETED_TRIAL_H_

#include <cstdint>
#include <limits>
#include <map>
#include <string>
#include <vector>

#include "absl/status/statusor.h"
#include "core/common/record.h"

namespace totalgrad::results {

struct CompletedTrial {
  std::string method;
  std::string seed;
  std::string variant;  // the job's grid point as shown ("" without a grid)
  // The trial's own verdict: final_eval_cost below its option "threshold".
  bool success = false;
  // The evaluation cost mean of the last episode; NaN when there is none.
  double final_eval_cost = std::numeric_limits<double>::quiet_NaN();
  // The rollout verdict's fraction held; NaN: the trial classified none.
  double held_fraction = std::numeric_limits<double>::quiet_NaN();
  std::string sweep;
  int64_t job_id = 0;
  int attempt = 0;   // the counting attempt
  int episodes = 0;  // episodes of that attempt
  // The job's options as stored: (key, canonical text) in the job's order.
  record::TextPairs options;
};

// The record's fields, named as every path names them.
const record::FieldTable<CompletedTrial>& CompletedTrialFields();
// The fields a coordinator reports per trial (the store's ListTrialResults,
// the wire's TrialResult): all but `sweep` and `options`, which the readers
// add. CompletedTrialFields is `sweep`, these in order, then `options`.
const record::FieldTable<CompletedTrial>& CompletedTrialResultFields();

// Where completed trials come from: a coordinator over gRPC (the CLI), the
// coordinator's own store (the dashboard, ControlService), a database file.
// Implementations say their thread-safety.
class ResultsReader {
 public:
  virtual ~ResultsReader() = default;

  // Every completed trial job of sweep `sweep`, in job id order, with its
  // job's options. NotFound (naming the sweep) when there is no such sweep;
  // an empty list when none of its jobs completed.
  virtual absl::StatusOr<std::vector<CompletedTrial>> CompletedTrials(
      const std::string& sweep) = 0;
};

// Sets each trial's `options` to its job's entry of `options_of` (moved
// out). InternalError naming the job and `sweep` when a trial's job has no
// entry: a result whose job is not listed completed. What both readers do
// after reading the results and then the completed jobs' options.
absl::Status AttachOptions(const std::string& sweep,
                           std::map<int64_t, record::TextPairs> options_of,
                           std::vector<CompletedTrial>* trials);

// The completed trials of several sweeps, in the order named (each sweep's
// `sweep` field set); the first error, prefixed with the sweep's name.
absl::StatusOr<std::vector<CompletedTrial>> ReadCompletedTrials(
    ResultsReader& reader, const std::vector<std::string>& sweeps);

}  // namespace totalgrad::results

#endif  // TOTALGRAD_RESULTS_COMPLETED_TRIAL_H_
