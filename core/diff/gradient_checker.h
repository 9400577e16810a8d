// Finite-difference derivative checking (Ceres GradientChecker style).
//
// A function f: R^n -> R^m is given as a callable that writes f(x) into an
// m-vector and returns false on numerical failure. NumericJacobian uses
// central differences with step h_j = relative_step * max(1, |x_j|).
// CheckJacobian compares an analytic Jacobian with the numeric one entry by
// entry with Ceres's criterion
//     |J_a - J_n| <= absolute_tolerance + relative_tolerance * max(|J_a|, |J_n|)
// and reports the worst entry. A deliberately wrong Jacobian must fail it (see
// tests/core/diff/gradient_checker_test.cc).
#ifndef TOTALGRAD_CORE_DIFF_GRADIENT_CHECKER_H_
#define TOTALGRAD_CORE_DIFF_GRADIENT_CHECKER_H_

#include <functional>
#include <string>

#include "core/common/types.h"

namespace totalgrad::diff {

using VectorFunction = std::function<bool(const Vector& x, Vector* value)>;

struct CheckOptions {
  double relative_step = 1e-6;
  double relative_tolerance = 1e-6;
  double absolute_tolerance = 1e-8;
};

// m x n central-difference Jacobian at x. Returns false if f fails at any
// probe point.
bool NumericJacobian(const VectorFunction& f, const Vector& x, double relative_step,
                     Matrix* jacobian);

struct CheckResult {
  bool ok = false;
  Matrix analytic;
  Matrix numeric;
  double max_abs_error = 0;
  double max_relative_error = 0;
  int worst_row = -1, worst_col = -1;
  std::string log;  // human-readable description of the worst entry
};

// Compares `analytic` (m x n) with the numeric Jacobian of f at x.
CheckResult CheckJacobian(const VectorFunction& f, const Vector& x, const Matrix& analytic,
                          const CheckOptions& options = {});

}  // namespace totalgrad::diff

#endif  // TOTALGRAD_CORE_DIFF_GRADIENT_CHECKER_H_
