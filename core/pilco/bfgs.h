// PILCO's policy optimiser: the BFGS branch of Rasmussen's `minimize` as
// PILCO ships it (pilco-spec.md 6.3), re-implemented from that description.
//
//  * dense inverse-Hessian BFGS update, direction r = -H g;
//  * one line search per iteration (an iteration counts as one of
//    max_line_searches, however many evaluations it takes), at most
//    max_evaluations_per_line_search evaluations each;
//  * the trial step is the previously accepted step (1 / (1 + |g|^2) the
//    first time), clipped so that the trial displacement has Euclidean length
//    in [1e-7, 1];
//  * cubic extrapolation (at most 5x, at least 1.1x the current step), then
//    cubic (or quadratic) interpolation kept 10 % away from the bracket ends;
//  * Wolfe-Powell acceptance with RHO = 0 (any non-increase of f) and
//    SIG = 0.5: |slope| <= SIG |initial slope|;
//  * a failed line search still moves to the best point seen, keeps H, and
//    two failures in a row end the optimisation;
//  * an evaluation that fails (returns false or gives non-finite numbers)
//    during extrapolation halves the step back towards the last good point
//    (one evaluation of the budget), as minimize does.
//
// Thread safety: Minimize is reentrant; the objective is called from the
// calling thread only.
#ifndef TOTALGRAD_CORE_PILCO_BFGS_H_
#define TOTALGRAD_CORE_PILCO_BFGS_H_

#include <functional>
#include <string>
#include <vector>

#include "core/common/types.h"

namespace totalgrad::pilco {

// Writes f(x) and its gradient (resized by the callee); false on failure.
using Objective = std::function<bool(const Vector& x, double* f, Vector* gradient)>;

struct BfgsOptions {
  int max_line_searches = 150;                // PILCO: opt.length = 150
  int max_evaluations_per_line_search = 30;   // PILCO: opt.MFEPLS = 30
  double sig = 0.5;                           // Wolfe-Powell curvature constant
  double rho = 0.0;                           // sufficient-decrease constant
  double interpolation_margin = 0.1;          // INT
  double max_extrapolation = 5.0;             // EXT
  double min_step_length = 1e-7;              // of the trial displacement
  double max_step_length = 1.0;
  // Polled once per line search; returning true stops with kCancelled.
  std::function<bool()> should_stop;
};

struct BfgsSummary {
  enum class Termination {
    kMaxLineSearches,      // the budget of line searches was used
    kTwoFailedLineSearches,
    kZeroGradient,
    kCancelled,
    kInitialEvaluationFailed,
  };
  Termination termination = Termination::kMaxLineSearches;
  int line_searches = 0;
  int evaluations = 0;
  int failed_line_searches = 0;
  int failed_evaluations = 0;    // objective returned false / non-finite
  double initial_value = 0;
  double final_value = 0;
  std::vector<double> history;   // f after each line search (entry 0: start)
  std::string BriefReport() const;
};

// Minimises from *x (in/out: on return the best point found, whose value is
// summary.final_value). Never returns a point worse than the start.
BfgsSummary MinimizeBfgs(const Objective& objective, const BfgsOptions& options, Vector* x);

}  // namespace totalgrad::pilco

#endif  // TOTALGRAD_CORE_PILCO_BFGS_H_
