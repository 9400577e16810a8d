// Internal: exception-free L-BFGS driver over LBFGSpp (Debian liblbfgspp-dev
// 0.1.0), used by GP hyperparameter training. Not a public API.
//
// LBFGSpp signals line-search failure by throwing and has no notion of a
// failed evaluation. MinimizeLbfgs keeps both inside: a failed evaluation is
// shown to the solver as a huge loss with zero gradient (the line search then
// shrinks the step), the best finite point ever evaluated is the result, and
// after a line-search failure the solver restarts from that point with fresh
// memory (steepest descent) if the failed run made progress; a run that fails
// without progress ends the minimisation (PILCO's minimize.m does the same).
// A line search that finds no decrease where the predicted decrease is itself
// below 1e-10 max(1, |f|) ends the minimisation as converged, not as a failure:
// near an optimum the decrease is lost in the round-off of f.
//
// Thread safety: no shared state.
#ifndef TOTALGRAD_CORE_GP_LBFGS_MINIMIZE_H_
#define TOTALGRAD_CORE_GP_LBFGS_MINIMIZE_H_

#include <functional>

#include "core/common/types.h"

namespace totalgrad::gp::internal {

// Writes f(x) into *value and, when `gradient` is not null, its gradient;
// returns false on numerical failure (values then unspecified).
using ObjectiveFunction = std::function<bool(const Vector& x, double* value, Vector* gradient)>;

struct MinimizeResult {
  Vector x;                        // best finite point evaluated
  double value = 0;                // f(x)
  int iterations = 0;              // accepted L-BFGS steps (completed line searches)
  int line_search_failures = 0;    // caught
  int non_finite_evaluations = 0;  // evaluations where f returned false
  int evaluations = 0;
};

// Minimises f from x0 with at most max_iterations line searches (>= 0; 0
// returns x0). Returns false, with *result holding only the counts, when f
// fails at x0.
bool MinimizeLbfgs(const ObjectiveFunction& f, const Vector& x0, int max_iterations,
                   MinimizeResult* result);

}  // namespace totalgrad::gp::internal

#endif  // TOTALGRAD_CORE_GP_LBFGS_MINIMIZE_H_
