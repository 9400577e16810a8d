// Shared test helpers (Ceres test_util style).
#ifndef TOTALGRAD_TESTS_TESTUTIL_TESTUTIL_H_
#define TOTALGRAD_TESTS_TESTUTIL_TESTUTIL_H_

#include <gtest/gtest.h>

#include <string>

#include "absl/status/status.h"
#include "core/common/types.h"

#define EXPECT_OK(expr)                                      \
  do {                                                       \
    const absl::Status _st = (expr);                         \
    EXPECT_TRUE(_st.ok()) << #expr << ": " << _st.ToString(); \
  } while (0)
#define ASSERT_OK(expr)                                      \
  do {                                                       \
    const absl::Status _st = (expr);                         \
    ASSERT_TRUE(_st.ok()) << #expr << ": " << _st.ToString(); \
  } while (0)

namespace totalgrad::testing {

// Max over entries of |a - b| / max(1, |a|, |b|) style mixed error; shapes must match.
::testing::AssertionResult MatricesNear(const Matrix& actual, const Matrix& expected,
                                        double abs_tolerance, double rel_tolerance);

// Directory for temporary files of one test (created, unique per process).
std::string TempDir();

}  // namespace totalgrad::testing

#endif  // TOTALGRAD_TESTS_TESTUTIL_TESTUTIL_H_
