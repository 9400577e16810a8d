#include "tests/testutil/testutil.h"

#include <algorithm>
#include <cmath>
#include <sstream>

namespace totalgrad::testing {

::testing::AssertionResult MatricesNear(const Matrix& actual, const Matrix& expected,
                                        double abs_tolerance, double rel_tolerance) {
  if (actual.rows() != expected.rows() || actual.cols() != expected.cols()) {
    return ::testing::AssertionFailure() << "shape " << actual.rows() << "x" << actual.cols()
                                         << " != " << expected.rows() << "x" << expected.cols();
  }
  for (Eigen::Index r = 0; r < actual.rows(); ++r) {
    for (Eigen::Index c = 0; c < actual.cols(); ++c) {
      const double a = actual(r, c), e = expected(r, c);
      const double tol = abs_tolerance + rel_tolerance * std::max(std::abs(a), std::abs(e));
      if (!(std::abs(a - e) <= tol)) {
        return ::testing::AssertionFailure()
               << "entry (" << r << "," << c << "): actual " << a << " expected " << e
               << " |diff| " << std::abs(a - e) << " > tol " << tol;
      }
    }
  }
  return ::testing::AssertionSuccess();
}

}  // namespace totalgrad::testing
