// Programmer-error checks (Ceres CHECK / SOPHUS_ENSURE style).
//
// TG_CHECK is for violated preconditions that are bugs in the caller (shape
// mismatch, null pointer): it prints the condition and location and aborts.
// Recoverable failures (bad user input, numerical failure) are never CHECKed:
// they travel as absl::Status or a false return value.
#ifndef TOTALGRAD_CORE_COMMON_CHECK_H_
#define TOTALGRAD_CORE_COMMON_CHECK_H_

#include <cstdio>
#include <cstdlib>

#define TG_CHECK(condition)                                                      \
  do {                                                                           \
    if (!(condition)) {                                                          \
      std::fprintf(stderr, "%s:%d: check failed: %s\n", __FILE__, __LINE__, #condition); \
      std::abort();                                                              \
    }                                                                            \
  } while (0)

#define TG_CHECK_EQ(a, b) TG_CHECK((a) == (b))

#endif  // TOTALGRAD_CORE_COMMON_CHECK_H_
