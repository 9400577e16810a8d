// Internal to core/study (study.cc, reference.cc): R timed runs of one
// estimator at one cell (P, H), on the substreams that give every estimator
// the same random numbers (common random numbers), and the statistics over
// them that the cells and the reference share.
#ifndef TOTALGRAD_CORE_STUDY_REPLICATES_H_
#define TOTALGRAD_CORE_STUDY_REPLICATES_H_

#include <chrono>
#include <cstdint>
#include <string>
#include <vector>

#include "core/common/types.h"
#include "core/estimators/estimator.h"

namespace totalgrad::study::internal {

using Clock = std::chrono::steady_clock;

double SecondsSince(Clock::time_point start);

// Substream index of replicate r of a cell (P, H): the same for every
// estimator (common random numbers). kind 0 = cells, 1 + k = reference
// estimator k (independent of the cells and of each other).
uint64_t StreamIndex(uint64_t kind, int horizon, int particles, int replicate);

// The median of `v`; NaN when empty.
double Median(std::vector<double> v);

// What R runs of one estimator at (P, H) produced.
struct Replicates {
  std::vector<Vector> estimates;  // finite ones
  std::vector<double> seconds;    // every successful Estimate call
  std::vector<double> objectives;
  std::vector<double> k_lr_sum;   // per step, over finite estimates that report k_LR
  int k_lr_count = 0;
  int nonfinite = 0;
  int errors = 0;
  std::string first_error;
  bool budget_hit = false;
};

// Runs `estimator` up to `replicates` times at `particles` on `problem` (at
// least two, then while `budget_seconds` lasts), replicate r on substream
// StreamIndex(kind, H, P, r) of `seed`; stops at the first error.
Replicates RunReplicates(estimators::Estimator* estimator, const estimators::Problem& problem,
                         int particles, int replicates, double budget_seconds, uint64_t seed,
                         uint64_t kind);

// Per coordinate: the mean of `estimates` (non-empty) and its standard error.
void MeanAndStandardError(const std::vector<Vector>& estimates, Vector* mean, Vector* se);

}  // namespace totalgrad::study::internal

#endif  // TOTALGRAD_CORE_STUDY_REPLICATES_H_
