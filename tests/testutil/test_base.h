// Test helpers every suite shares, with no dependency beyond GoogleTest and
// abseil (the storage and scheduler tests must not link the numerical core):
// status assertions for absl::Status and absl::StatusOr, and temporary
// directories. tests/testutil/testutil.h adds the core's matrix helpers;
// tests/service/service_testutil.h the service's builders and fakes.
#ifndef TOTALGRAD_TESTS_TESTUTIL_TEST_BASE_H_
#define TOTALGRAD_TESTS_TESTUTIL_TEST_BASE_H_

#include <gtest/gtest.h>

#include <string>
#include <utility>

#include "absl/status/status.h"
#include "absl/status/statusor.h"

// TG_EXPECT_OK(expr) / TG_ASSERT_OK(expr): expr is an absl::Status or an
// absl::StatusOr<T>; the failure message shows the expression and the status.
#define TG_EXPECT_OK(expr)                                              \
  do {                                                                  \
    const ::absl::Status tg_st_ = ::totalgrad::testing::ToStatus(expr); \
    EXPECT_TRUE(tg_st_.ok()) << #expr << ": " << tg_st_.ToString();     \
  } while (0)
#define TG_ASSERT_OK(expr)                                              \
  do {                                                                  \
    const ::absl::Status tg_st_ = ::totalgrad::testing::ToStatus(expr); \
    ASSERT_TRUE(tg_st_.ok()) << #expr << ": " << tg_st_.ToString();     \
  } while (0)
// TG_ASSERT_OK_AND_ASSIGN(lhs, expr): asserts that the StatusOr expr is OK
// and moves its value into lhs (a declaration or an lvalue).
#define TG_ASSERT_OK_AND_ASSIGN(lhs, expr)                                     \
  auto TG_TU_CONCAT(tg_sor_, __LINE__) = (expr);                               \
  ASSERT_TRUE(TG_TU_CONCAT(tg_sor_, __LINE__).ok())                            \
      << #expr << ": " << TG_TU_CONCAT(tg_sor_, __LINE__).status().ToString(); \
  lhs = std::move(*TG_TU_CONCAT(tg_sor_, __LINE__))
#define TG_TU_CONCAT_INNER(a, b) a##b
#define TG_TU_CONCAT(a, b) TG_TU_CONCAT_INNER(a, b)

namespace totalgrad::testing {

inline absl::Status ToStatus(const absl::Status& status) { return status; }
template <typename T>
absl::Status ToStatus(const absl::StatusOr<T>& status_or) {
  return status_or.status();
}

// A fresh empty directory for one test (under $TEST_TMPDIR or the system's
// temporary directory), unique across processes and calls; not removed.
std::string MakeTempDir();

}  // namespace totalgrad::testing

#endif  // TOTALGRAD_TESTS_TESTUTIL_TEST_BASE_H_
