// A Status with the place it arose put in front of its message, keeping its
// code: "step 3: dynamics GP: kernel matrix not PSD".
#ifndef TOTALGRAD_CORE_COMMON_STATUS_CONTEXT_H_
#define TOTALGRAD_CORE_COMMON_STATUS_CONTEXT_H_

#include "absl/status/status.h"
#include "absl/strings/str_cat.h"
#include "absl/strings/string_view.h"

namespace totalgrad {

// OK stays OK; otherwise the same code with "where: " before the message.
inline absl::Status WithContext(const absl::Status& status, absl::string_view where) {
  if (status.ok()) return status;
  return absl::Status(status.code(), absl::StrCat(where, ": ", status.message()));
}

}  // namespace totalgrad

#endif  // TOTALGRAD_CORE_COMMON_STATUS_CONTEXT_H_
