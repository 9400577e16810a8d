// Hyperparameter training: maximise the log marginal likelihood of each output
// plus PILCO's hyperparameter penalty (pilco-spec.md 4.4, "hypCurb"):
//
//   loss_a(h) = NLML_a(h) + sum_m ((log l_m - log std_m) / log(ls))^p
//                         + ((log sf - log sn) / log(snr))^p
//
// with p = 30, ls = 100, snr = 1000 and std_m the (N-1)-normalised standard
// deviation of input column m. Minimised per output with L-BFGS (LBFGSpp),
// warm-started from the given hyperparameters. A line-search failure is caught:
// the best point seen so far is kept and the failure is counted in the summary;
// as in PILCO's minimize.m, L-BFGS then restarts from that point (within the
// same iteration budget) if the failed run had made progress. A constant input
// column (std 0) uses std 1 in the penalty, as in InitialHyperparameters.
//
// Thread safety: free functions, no shared state.
#ifndef TOTALGRAD_CORE_GP_TRAINING_H_
#define TOTALGRAD_CORE_GP_TRAINING_H_

#include <string>
#include <vector>

#include "absl/status/statusor.h"
#include "core/common/option_table.h"
#include "core/common/types.h"
#include "core/gp/gp.h"

namespace totalgrad::gp {

struct PenaltyOptions {
  bool enabled = true;
  double lengthscale_ratio = 100.0;  // curb.ls
  double signal_to_noise = 1000.0;   // curb.snr
  int power = 30;                    // p

  // Trial option keys gp_penalty (enabled), gp_penalty_lengthscale_ratio,
  // gp_penalty_signal_to_noise, gp_penalty_power.
  static const OptionTable<PenaltyOptions>& Table();
  // InvalidArgument naming the key: ratios must be finite and > 1 (their logs
  // divide), the power an even integer >= 2 (the penalty must grow on both
  // sides).
  absl::Status Validate() const;
  bool operator==(const PenaltyOptions&) const = default;
};

struct TrainingOptions {
  int max_iterations = 300;  // L-BFGS iterations per output (PILCO: 300 line searches)
  PenaltyOptions penalty;

  // Trial option keys gp_iterations and the penalty's (PenaltyOptions::Table()).
  static const OptionTable<TrainingOptions>& Table();
  // InvalidArgument naming the key (gp_iterations < 0, or the penalty's).
  absl::Status Validate() const;
  bool operator==(const TrainingOptions&) const = default;
};

struct TrainingSummary {
  std::vector<double> final_loss;     // per output, NLML + penalty at the result
  std::vector<int> iterations;        // per output: accepted L-BFGS steps (line searches)
  int line_search_failures = 0;       // caught and recovered from
  int non_finite_evaluations = 0;     // loss evaluations that were not finite
  std::string BriefReport() const;
};

// NLML of one output plus the penalty, and its gradient with respect to the
// packed log hyperparameters [log l_1..E, log sf, log sn] (E + 2). `input_std`
// (E, entries > 0) is the per-column input std used by the penalty. `gradient` may be
// null. Returns false (value unspecified) if K is not positive definite or a
// value is not finite.
bool PenalisedNlml(const RowMatrix& inputs, const Vector& targets, const Vector& input_std,
                   const Vector& packed_log_hyp, const PenaltyOptions& penalty, double* value,
                   Vector* gradient);

// PILCO's initialisation: log l = log std(inputs), log sf = log std(targets_a),
// log sn = log(std(targets_a) / 10). Zero stds are replaced by 1.
GpHyperparameters InitialHyperparameters(const RowMatrix& inputs, const RowMatrix& targets);

// Trains every output in place, starting from *hyperparameters (warm start).
// On success *hyperparameters holds the best point found. Errors:
// InvalidArgument for bad shapes / non-finite data (named), FailedPrecondition
// if no finite loss could be evaluated even at the start point (then
// *hyperparameters is left unchanged).
absl::StatusOr<TrainingSummary> TrainHyperparameters(const RowMatrix& inputs,
                                                     const RowMatrix& targets,
                                                     const TrainingOptions& options,
                                                     GpHyperparameters* hyperparameters);

}  // namespace totalgrad::gp

#endif  // TOTALGRAD_CORE_GP_TRAINING_H_
