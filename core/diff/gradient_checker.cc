#include "core/diff/gradient_checker.h"

#include <algorithm>
#include <cmath>
#include <sstream>

namespace totalgrad::diff {

bool NumericJacobian(const VectorFunction& f, const Vector& x, double relative_step,
                     Matrix* jacobian) {
  Vector f0;
  if (!f(x, &f0)) return false;
  jacobian->resize(f0.size(), x.size());
  Vector xp = x, fp, fm;
  for (Eigen::Index j = 0; j < x.size(); ++j) {
    const double h = relative_step * std::max(1.0, std::abs(x(j)));
    xp(j) = x(j) + h;
    if (!f(xp, &fp)) return false;
    xp(j) = x(j) - h;
    if (!f(xp, &fm)) return false;
    xp(j) = x(j);
    if (fp.size() != f0.size() || fm.size() != f0.size()) return false;
    jacobian->col(j) = (fp - fm) / (2.0 * h);
  }
  return true;
}

CheckResult CheckJacobian(const VectorFunction& f, const Vector& x, const Matrix& analytic,
                          const CheckOptions& options) {
  CheckResult result;
  result.analytic = analytic;
  if (!NumericJacobian(f, x, options.relative_step, &result.numeric)) {
    result.log = "function evaluation failed at a probe point";
    return result;
  }
  if (result.numeric.rows() != analytic.rows() || result.numeric.cols() != analytic.cols()) {
    std::ostringstream os;
    os << "shape mismatch: analytic " << analytic.rows() << "x" << analytic.cols() << ", numeric "
       << result.numeric.rows() << "x" << result.numeric.cols();
    result.log = os.str();
    return result;
  }
  result.ok = true;
  double worst_excess = -1;
  for (Eigen::Index r = 0; r < analytic.rows(); ++r) {
    for (Eigen::Index c = 0; c < analytic.cols(); ++c) {
      const double a = analytic(r, c), n = result.numeric(r, c);
      const double err = std::abs(a - n);
      const double scale = std::max(std::abs(a), std::abs(n));
      const double tol = options.absolute_tolerance + options.relative_tolerance * scale;
      if (!std::isfinite(a) || !(err <= tol)) result.ok = false;
      result.max_abs_error = std::max(result.max_abs_error, err);
      if (scale > 0) result.max_relative_error = std::max(result.max_relative_error, err / scale);
      const double excess = std::isfinite(err) ? err / tol : 1e300;
      if (excess > worst_excess) {
        worst_excess = excess;
        result.worst_row = static_cast<int>(r);
        result.worst_col = static_cast<int>(c);
      }
    }
  }
  std::ostringstream os;
  if (result.worst_row >= 0) {
    os << "worst entry (" << result.worst_row << "," << result.worst_col << "): analytic "
       << analytic(result.worst_row, result.worst_col) << " numeric "
       << result.numeric(result.worst_row, result.worst_col) << "; max abs error "
       << result.max_abs_error << ", max relative error " << result.max_relative_error;
  }
  result.log = os.str();
  return result;
}

}  // namespace totalgrad::diff
