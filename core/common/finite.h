// Validation helpers for user-supplied numbers.
#ifndef TOTALGRAD_CORE_COMMON_FINITE_H_
#define TOTALGRAD_CORE_COMMON_FINITE_H_

#include <cmath>
#include <string>

#include <Eigen/Core>

#include "absl/status/status.h"
#include "absl/strings/str_cat.h"

namespace totalgrad {

// OK, or InvalidArgument naming `name` and the first non-finite entry.
template <typename Derived>
absl::Status CheckFinite(const Eigen::MatrixBase<Derived>& m, const std::string& name) {
  for (Eigen::Index r = 0; r < m.rows(); ++r) {
    for (Eigen::Index c = 0; c < m.cols(); ++c) {
      if (!std::isfinite(m(r, c))) {
        return absl::InvalidArgumentError(
            absl::StrCat(name, "(", r, ", ", c, ") is not finite: ", m(r, c)));
      }
    }
  }
  return absl::OkStatus();
}

}  // namespace totalgrad

#endif  // TOTALGRAD_CORE_COMMON_FINITE_H_
