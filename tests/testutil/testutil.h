// Shared test helpers of the core and client suites (Ceres test_util
// style): tests/testutil/test_base.h (status assertions, temporary
// directories) plus matrix comparisons.
#ifndef TOTALGRAD_TESTS_TESTUTIL_TESTUTIL_H_
#define TOTALGRAD_TESTS_TESTUTIL_TESTUTIL_H_

#include <gtest/gtest.h>

#include <string>

#include "absl/status/status.h"
#include "core/common/types.h"
#include "tests/testutil/test_base.h"

namespace totalgrad::testing {

// Max over entries of |a - b| / max(1, |a|, |b|) style mixed error; shapes must match.
::testing::AssertionResult MatricesNear(const Matrix& actual, const Matrix& expected,
                                        double abs_tolerance, double rel_tolerance);

}  // namespace totalgrad::testing

#endif  // TOTALGRAD_TESTS_TESTUTIL_TESTUTIL_H_
