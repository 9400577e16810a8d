// RETURN_IF_ERROR / ASSIGN_OR_RETURN for absl::Status and absl::StatusOr.
#ifndef TOTALGRAD_RUNTIME_STATUS_MACROS_H_
#define TOTALGRAD_RUNTIME_STATUS_MACROS_H_

#include <utility>

#include "absl/status/status.h"
#include "absl/status/statusor.h"

#define TG_STATUS_CONCAT_INNER(a, b) a##b
#define TG_STATUS_CONCAT(a, b) TG_STATUS_CONCAT_INNER(a, b)

#define RETURN_IF_ERROR(expr)                                              \
  do {                                                                     \
    const ::absl::Status TG_STATUS_CONCAT(status_, __LINE__) = (expr);    \
    if (!TG_STATUS_CONCAT(status_, __LINE__).ok())                         \
      return TG_STATUS_CONCAT(status_, __LINE__);                          \
  } while (0)

#define TG_ASSIGN_OR_RETURN_IMPL(tmp, lhs, expr) \
  auto tmp = (expr);                             \
  if (!tmp.ok()) return tmp.status();            \
  lhs = std::move(*tmp)

// `lhs` may be a declaration ("Foo foo") or an existing variable.
#define ASSIGN_OR_RETURN(lhs, expr) \
  TG_ASSIGN_OR_RETURN_IMPL(TG_STATUS_CONCAT(status_or_, __LINE__), lhs, expr)

#endif  // TOTALGRAD_RUNTIME_STATUS_MACROS_H_
